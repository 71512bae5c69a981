"""Compiled (numba) forms of :mod:`gyrosim.rotations` hot spots, bit-identical to the numpy forms.

Each kernel performs the numpy reference's floating-point operations in the same order (no
fast-math, so no fused multiply-add), so results are equal to the last bit, not to rounding:
``tests/test_rotations_kernels.py`` compares them bit for bit.  What changes is memory traffic: one
pass in place instead of whole-array temporaries per term.
"""

from __future__ import annotations

from numba import njit

__all__ = ["prefix_product_inplace"]


@njit(cache=True)
def prefix_product_inplace(out):  # pragma: no cover - compiled
    """Hillis–Steele prefix scan of Hamilton products along axis 0 of ``out`` (n, m, 4), in place.

    Pass with shift s (1, 2, 4, …): out[i] ← out[i − s] ⊗ out[i] for every i ≥ s, all reading the
    values before the pass — exactly :func:`gyrosim.rotations.quat_cumulative_product`'s grouping.
    Walking i downwards lets one array hold both: out[i − s] is read before it is overwritten.
    Hamilton product (w, x, y, z), each component summed left to right as in ``quat_multiply``.
    """
    n, m = out.shape[0], out.shape[1]
    shift = 1
    while shift < n:
        for i in range(n - 1, shift - 1, -1):
            j = i - shift
            for c in range(m):
                pw, px, py, pz = out[j, c, 0], out[j, c, 1], out[j, c, 2], out[j, c, 3]
                qw, qx, qy, qz = out[i, c, 0], out[i, c, 1], out[i, c, 2], out[i, c, 3]
                out[i, c, 0] = pw * qw - px * qx - py * qy - pz * qz
                out[i, c, 1] = pw * qx + px * qw + py * qz - pz * qy
                out[i, c, 2] = pw * qy - px * qz + py * qw + pz * qx
                out[i, c, 3] = pw * qz + px * qy - py * qx + pz * qw
        shift *= 2
