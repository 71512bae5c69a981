"""Our overlapping Allan deviation against allantools (the reference it replaced at run time; allantools is in
the test extra): the same τ, the same σ(τ), the same counts, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.noise.allan import allan_deviation, overlapping_allan_deviation


def _record(seed: int, n: int, rate_hz: float) -> np.ndarray:
    """White noise + a random walk on a large constant rate (the mean removal matters), rad/s."""
    rng = np.random.default_rng(seed)
    return 5.0 + rng.normal(0.01, 1e-3, n) + np.cumsum(rng.normal(0.0, 1e-6, n))


@pytest.mark.parametrize("seed,n,rate_hz", [(0, 10_000, 100.0), (1, 333, 7.5), (2, 50_000, 200.0)])
def test_overlapping_allan_deviation_is_allantools_oadev(seed, n, rate_hz):
    import allantools  # the test extra's reference

    x = _record(seed, n, rate_hz)
    T = n / rate_hz
    calib_taus = np.logspace(math.log10(2 / rate_hz), math.log10(T / 5), int(8 * math.log10(T * rate_hz / 10)))
    # the edges: below one sample, one sample, a cluster longer than half the record, longer than the record
    edges = np.array([0.1 / rate_hz, 1 / rate_hz, 3 / rate_hz, 0.49 * T, 0.6 * T, T, 2 * T])
    for taus in (calib_taus, edges):
        t_ref, adev_ref, _, n_ref = allantools.oadev(x, rate=rate_hz, data_type="freq", taus=taus)
        t, adev, counts = overlapping_allan_deviation(x, rate_hz, taus)
        # the same operations in the same order: equal to the last bit, not within a tolerance
        np.testing.assert_array_equal(t, t_ref)
        np.testing.assert_array_equal(adev, adev_ref)
        np.testing.assert_array_equal(counts, n_ref)


def test_allan_deviation_of_white_noise_follows_its_density():
    # white noise of density N (rad/s/√Hz): σ(τ) = N/√τ; at τ = 1 s over 1000 s the estimate's relative 1σ is
    # ≈ 1/√(2(M − 1)) with M = 1000 clusters, 2.2 %: 5σ is 11 %
    rate, density = 100.0, 2e-3
    x = np.random.default_rng(7).normal(0.0, density * math.sqrt(rate), 100_000)
    curve = allan_deviation(x, rate)
    k = int(np.argmin(np.abs(curve.tau_s - 1.0)))
    assert curve.tau_s[k] == pytest.approx(1.0, rel=0.2)
    expected = density / math.sqrt(curve.tau_s[k])
    assert curve.adev[k] == pytest.approx(expected, rel=5 * curve.relative_error[k])
