"""Saturation: runs of ≥ 3 equal samples at a channel's extreme value (clipped at the rail), in
channels where equal consecutive samples are otherwise rare (< 5 % of the other steps): a
noise-free or coarsely quantized channel repeats values everywhere, and a flat top there says
nothing."""

from __future__ import annotations

import numpy as np

__all__ = ["saturated_samples"]


def saturated_samples(x: np.ndarray, run: int = 3) -> np.ndarray:
    """Samples in runs of ≥ ``run`` equal values at the channel's extreme |value| (per sample)."""
    bad = np.zeros(x.shape[0], dtype=bool)
    for c in np.ascontiguousarray(np.asarray(x, dtype=float).T):  # channel-major: column passes are slow
        peak = float(np.max(np.abs(c)))
        if peak == 0:
            continue
        equal = c[1:] == c[:-1]
        at = np.abs(c) >= peak * (1 - 1e-9)
        pair = at[1:] & at[:-1] & equal  # sample k and k+1 equal and at the rail
        others = equal[~pair]
        if not pair.any() or (others.size and others.mean() > 0.05):
            continue  # repeats are normal away from the extreme too: a flat top is no evidence of a rail
        edges = np.diff(np.concatenate([[0], pair.astype(np.int8), [0]]))
        starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        for s0, s1 in zip(starts, stops):
            if s1 - s0 + 1 >= run:  # s1 - s0 equal pairs = s1 - s0 + 1 samples
                bad[s0 : s1 + 1] = True
    return bad
