"""Shared fixtures: simulated sessions are expensive (~1.5 s), so each is made once per run.

The tests mirror calib's folders (``tests/session/`` for ``calib/session/``…); the independent generators
and the bad-input catalogue they share stay here, at the top, importable by name from every folder.
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import pytest

from gyrosim.simulate import simulate_truth

sys.path.insert(0, str(Path(__file__).resolve().parent))  # independent_generator, bad_inputs, … by name


@functools.lru_cache(maxsize=None)
def session(hand: str, seed: int = 1, rate_hz: float = 100.0, schedule: str = "zhou2020"):
    """A cached zhou2020 truth recording (read-only arrays, safe to share)."""
    return simulate_truth(schedule, hand, rate_hz, seed=seed)


@pytest.fixture(scope="session")
def ideal_session():
    return session("ideal")


@pytest.fixture(scope="session")
def typical_session():
    return session("typical")
