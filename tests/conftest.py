"""Shared fixtures: simulated sessions are expensive (~1.5 s), so each is made once per run."""

from __future__ import annotations

import functools

import pytest

from gyrosim.simulate import simulate_truth


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
