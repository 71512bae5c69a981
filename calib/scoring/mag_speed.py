"""Speed of the magnetometer fits (``calib mag-bench``), as ratios against a baseline measured in
the same run, interleaved (A B A B …, best of ``repeats``) because the machine is shared.

Session: zhou2020 (171 s ≈ 3 min) at 100 Hz, typical hand, the ``mpu9250_9axis`` device.
Baseline: the linear least-squares sphere fit |m|² = 2hᵀm + c (one ``numpy.linalg.lstsq`` on
N × 4), the cheapest hard-iron estimate there is.  Rows: the ellipsoid fit alone
(:func:`calib.mag.ellipsoid.fit_ellipsoid`), the attitude-aided fit alone (gravity reference +
:func:`calib.mag.aided.fit_aided`), and ``calibrate_magnetometer`` end to end with each method
(checks, disturbance loop, consistency check, covariance propagation).  BLAS single-threaded
throughout, as ``calibrate_magnetometer`` runs it: one core.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["run_mag_bench"]


def _best_interleaved(fns: list, repeats: int) -> list[float]:
    best = [float("inf")] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            best[i] = min(best[i], time.perf_counter() - t0)
    return best


def run_mag_bench(repeats: int = 5, seed: int = 1) -> dict[str, float]:
    """Time the magnetometer fits (module docstring) on one simulated session, print the table and
    return the best time (s) of each row by name."""
    from gyrosim.simulate import simulate

    from calib.mag.aided import fit_aided
    from calib.mag.calibrate import calibrate_magnetometer
    from calib.mag.ellipsoid import fit_ellipsoid
    from calib.mag.gravity import gravity_reference
    from calib.mag.lsq import block_index

    rec = simulate("zhou2020", "typical", "mpu9250_9axis", 100.0, seed=seed)
    m = np.asarray(rec.mag_ut)
    blocks = block_index(rec.n, 100)

    def baseline():
        a = np.column_stack([2 * m, np.ones(m.shape[0])])
        np.linalg.lstsq(a, np.sum(m * m, axis=1), rcond=None)

    def ellipsoid():
        fit_ellipsoid(m, blocks)

    e = fit_ellipsoid(m, blocks)

    def aided():
        g = gravity_reference(rec)
        fit_aided(m, g.up_body, g.quasi_static, blocks, e.l_matrix, e.centre)

    def full_e():
        calibrate_magnetometer(rec, "ellipsoid")

    def full_a():
        calibrate_magnetometer(rec, "aided")

    names = ["baseline: linear sphere lstsq", "ellipsoid fit", "attitude-aided fit (incl. gravity reference)",
             "calibrate_magnetometer, ellipsoid", "calibrate_magnetometer, aided"]
    fns = [baseline, ellipsoid, aided, full_e, full_a]
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):  # one core, as calibrate_magnetometer runs
        for fn in fns:  # warm-up (imports, caches)
            fn()
        times = _best_interleaved(fns, repeats)
    print(f"zhou2020 {rec.duration_s:.0f} s at {rec.rate_hz:g} Hz ({rec.n} samples), mpu9250_9axis; best of {repeats}, "
          "interleaved")
    print(f"{'':<46} {'s':>8} {'× baseline':>11} {'target':>8}")
    targets = {"ellipsoid fit": 0.1, "attitude-aided fit (incl. gravity reference)": 2.0}
    for name, t in zip(names, times):
        tgt = f"< {targets[name]:g} s" if name in targets else ""
        print(f"{name:<46} {t:8.4f} {t / times[0]:11.1f} {tgt:>8}")
    return dict(zip(names, times))
