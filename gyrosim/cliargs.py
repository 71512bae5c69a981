"""Validated numeric command-line options: finite, signed and ranged as the option needs, with the
accepted range in the message.  Shared by the ``gyrosim`` and ``calib`` parsers.

Each factory returns an ``argparse`` ``type=`` callable; a bad value makes argparse print
``error: argument --rate: must be a finite number in (0, 100000] Hz, got 'nan'`` and exit 2.
"""

from __future__ import annotations

import argparse
import math
from typing import Callable

__all__ = ["number", "integer", "seed", "SEED_MAX", "positive_list"]

SEED_MAX = 2**32 - 1  # numpy's legacy seed range; also fits the HDF5 int64 attribute the seed is stored in


def _fmt(v: float) -> str:
    if float(v).is_integer() and abs(v) < 1e10:
        return str(int(v))
    return f"{v:g}"


def _interval(lo: float | None, hi: float | None, lo_open: bool, hi_open: bool, unit: str) -> str:
    a = "(-∞" if lo is None else f"{'(' if lo_open else '['}{_fmt(lo)}"
    b = "∞)" if hi is None else f"{_fmt(hi)}{')' if hi_open else ']'}"
    return f"{a}, {b}" + (f" {unit}" if unit else "")


def number(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False, hi_open: bool = False,
           unit: str = "") -> Callable[[str], float]:
    """A finite float in the interval [lo, hi] (open ends with ``lo_open``/``hi_open``; None: unbounded)."""
    rng = _interval(lo, hi, lo_open, hi_open, unit)

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number in {rng}, got {text!r}") from None
        if not math.isfinite(v) or (lo is not None and (v < lo or (lo_open and v == lo))) or \
                (hi is not None and (v > hi or (hi_open and v == hi))):
            raise argparse.ArgumentTypeError(f"must be a finite number in {rng}, got {text!r}")
        return v

    parse.__name__ = "number"
    return parse


def integer(lo: int | None = None, hi: int | None = None, *, unit: str = "") -> Callable[[str], int]:
    """An integer in [lo, hi] (None: unbounded)."""
    rng = _interval(lo, hi, False, False, unit)

    def parse(text: str) -> int:
        try:
            v = int(text.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer in {rng}, got {text!r}") from None
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"must be an integer in {rng}, got {text!r}")
        return v

    parse.__name__ = "integer"
    return parse


def seed(text: str) -> int:
    """A random seed: an integer in [0, 2³² − 1]."""
    return integer(0, SEED_MAX)(text)


seed.__name__ = "seed"


def positive_list(unit: str = "") -> Callable[[str], tuple[float, ...]]:
    """Comma-separated finite numbers > 0 (e.g. severity factors)."""
    one = number(0, None, lo_open=True, unit=unit)

    def parse(text: str) -> tuple[float, ...]:
        parts = [p.strip() for p in text.split(",") if p.strip()]
        if not parts:
            raise argparse.ArgumentTypeError("needs at least one number")
        return tuple(one(p) for p in parts)

    parse.__name__ = "list"
    return parse
