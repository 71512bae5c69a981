"""Means over consecutive time blocks: the one averaging that the temperature models (10 s blocks
of a chamber record) and the drift estimate of ``calib closeloop`` (≤ 400 blocks) share."""

from __future__ import annotations

import numpy as np

__all__ = ["time_block_index", "block_means"]


def time_block_index(t_s: np.ndarray, block_s: float) -> np.ndarray:
    """Block of each sample: ⌊(t − t₀) / block_s⌋ (N,) ints, t in s."""
    t = np.asarray(t_s, dtype=float)
    return np.floor((t - t[0]) / block_s).astype(int)


def block_means(k: np.ndarray, x: np.ndarray, n_blocks: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Means of x (N, ...) over the samples of each block k (N,) ≥ 0, and the sample counts.

    Returns (means (B, ...), counts (B,)), B = ``n_blocks`` or max(k) + 1; an empty block has mean 0
    and count 0 (callers keep ``counts > 0``)."""
    x = np.asarray(x, dtype=float)
    nb = int(k.max()) + 1 if n_blocks is None else int(n_blocks)
    counts = np.bincount(k, minlength=nb)
    flat = x.reshape(x.shape[0], -1)
    sums = np.stack([np.bincount(k, flat[:, c], minlength=nb) for c in range(flat.shape[1])], axis=1)
    return (sums / np.maximum(counts, 1)[:, None]).reshape((nb,) + x.shape[1:]), counts
