"""``calib bench``: how long a calibration takes, as ratios against the paper's filter in the same run.

The session: zhou2020 (171 s at 100 Hz, 17 101 samples), ideal hand, the MPU-9250 preset (raw
accelerometer).  Rows, run interleaved (A B C … A B C …) so that all see the same machine state,
best of ``repeats``:

* ``kf_session_r`` in filterpy — :func:`calib.session.paper.calibrate` with ``accelerometer="calibrated"``
  and ``engine="filterpy"``: the paper's 9 gyro states with one external-acceleration allowance for
  the session (the registered ``kf_session_r``, not the paper's ``kf``, whose R is the
  accelerometer noise alone), in the filterpy filter without the hand cross-check: what ``calib
  run`` ran before the accelerometer states (the baseline, 1.00);
* ``calib run`` now — 21 states (gyro bias, the accelerometer's 9 parameters), the |f| = g stage,
  observability and consistency checks, compiled;
* the same with ``--method iterated_joint`` and with ``--accelerometer calibrated`` (these include the hand
  cross-check, which runs ``kf_hand`` once);
* the paper's ``kf`` compiled without the hand cross-check, ``kf_hand`` and ``kf_hand_joint`` (``calib run
  --method hand``: + the accelerometer's 9 states; their speed target is ≤ 1 s for this 3-minute session
  on one core, read beside ``kf`` in the same run);
* the kernel alone (no preparation), batches of 1 and ``batch`` sessions, per filter-sample.

The agreement of the compiled 21-state filter with its filterpy reference on this session is
printed too (max |Δθ|).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from gyrosim.recording import Recording

__all__ = ["run_bench", "ClosedLoopTiming", "closeloop_bench"]


def run_bench(batch: int = 50, repeats: int = 3, seed: int = 0) -> list[tuple[str, float, float]]:
    """Time each row of the module docstring on one simulated session, print the table and return
    (row, best time in s, ratio to the filterpy baseline) per row."""
    from gyrosim.simulate import simulate

    from calib.session.hand.filter import kf_hand
    from calib.session.kernel import run_filter
    from calib.session.model import JOINT
    from calib.session.paper import PaperParams, calibrate, paper_filter, prepare, session_filter_run

    rec = simulate("zhou2020", "ideal", "mpu9250", 100.0, seed=seed)
    prep = prepare(rec, accelerometer="estimate")
    a = prep.start
    n = rec.n - a
    calibrate(rec, "kf_joint")  # compile and warm every path once
    cases = {
        "kf_session_r (9 states, filterpy)": lambda: calibrate(
            rec, "kf_session_r", engine="filterpy", hand_check=False
        ),
        "calib run (21 states, compiled)": lambda: calibrate(rec, "kf_joint"),
        "calib run --method iterated_joint": lambda: calibrate(rec, "iterated_joint"),
        "calib run --accelerometer calibrated": lambda: calibrate(rec, "kf_session_r"),
        "kf (paper, 9 states, compiled, no hand check)": lambda: paper_filter(rec, PaperParams(), name="kf",
                                                                             hand_check=False),
        "kf_hand (33 states: + c_b, s_T, δ, 3 passes, compiled)": lambda: kf_hand(rec),
        "kf_hand_joint (45 states: + s_T, c_a, δ, α, 3 passes)": lambda: kf_hand(rec, accelerometer="estimate"),
    }
    best = {k: float("inf") for k in cases}
    for _ in range(max(1, repeats)):
        for name, fn in cases.items():
            t0 = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - t0)
    g, f = rec.gyro_rad_s[None, a:], rec.acc_m_s2[None, a:]
    run_filter(g[:, :200], f[:, :200], rec.t_s[a:a + 200], prep.quat0_nb[None], prep.theta0[None], prep.p0, JOINT,
               prep.config, rec.rate_hz)  # warm
    kernel = {}
    for b in (1, batch):
        t0 = time.perf_counter()
        run_filter(np.repeat(g, b, 0), np.repeat(f, b, 0), rec.t_s[a:], np.repeat(prep.quat0_nb[None], b, 0),
                   prep.theta0[None], prep.p0, JOINT, prep.config, rec.rate_hz)
        kernel[b] = time.perf_counter() - t0
    ref = session_filter_run(prep, rec, prep.theta0, prep.quat0_nb, prep.p0, "filterpy", False)
    fast = session_filter_run(prep, rec, prep.theta0, prep.quat0_nb, prep.p0, "compiled", False)
    diff = float(np.max(np.abs(ref.theta - fast.theta)))
    base = best["kf_session_r (9 states, filterpy)"]
    print(f"zhou2020, ideal hand, mpu9250 (raw accelerometer), {n} filter samples; best of {repeats}, interleaved")
    print(f"max |θ compiled − θ filterpy| (21 states) = {diff:.1e}")
    print(f"{'':<44} {'s':>8} {'× baseline':>13} {'µs/sample':>10}")
    rows = []
    for name, sec in best.items():
        rows.append((name, sec, sec / base))
        print(f"{name:<44} {sec:8.3f} {sec / base:13.3f} {sec / n * 1e6:10.2f}")
    for b, sec in kernel.items():
        name = f"kernel only (21 states), batch {b}"
        rows.append((name, sec, sec / base))
        print(f"{name:<44} {sec:8.3f} {sec / base:13.3f} {sec / (n * b) * 1e6:10.2f}")
    return rows


@dataclass(frozen=True)
class ClosedLoopTiming:
    """``calib closeloop`` against ``calib run``'s filter on one recording (wall s, same run)."""

    recording: str
    samples: int
    closeloop_s: float
    filter_s: float

    @property
    def ratio(self) -> float:
        return self.closeloop_s / self.filter_s


def closeloop_bench(cases: list[tuple[str, Recording]] | None = None) -> list[ClosedLoopTiming]:
    """``calib closeloop-bench``: closeloop wall time on ~3-minute recordings against the Zhou filter
    (``calibrate(rec, "kf_session_r", accelerometer="calibrated")``: kf_joint's filter with the accelerometer
    calibrated, as closeloop fits only the gyro; the zhou2020 schedule cannot determine the accelerometer, and with
    it estimated the filter refuses the session) on the same
    data, in the same run; the simulated zhou2020 session always, BROAD 07 when the dataset is present.  Each
    closeloop is run once first to warm caches (numba, FFT plans), so both timings are steady state.  ``cases``:
    (name, recording) pairs instead of those two."""
    from gyrosim.loaders import available_datasets, load_dataset
    from gyrosim.simulate import simulate

    from calib.closeloop import run_closeloop
    from calib.closeloop.suite import BASE_SENSOR
    from calib.session.paper import calibrate

    if cases is None:
        cases = [("zhou2020, typical hand, 100 Hz (simulated)",
                  simulate("zhou2020", "typical", BASE_SENSOR, 100.0, seed=0))]
        if "broad/07_undisturbed_fast_rotation_B" in available_datasets():
            cases.append(("BROAD 07 fast rotation, 285.7 Hz (measured)",
                          load_dataset("broad/07_undisturbed_fast_rotation_B")))
    out = []
    for name, rec in cases:
        run_closeloop(rec)
        t0 = time.perf_counter()
        run_closeloop(rec)
        t_cl = time.perf_counter() - t0
        t0 = time.perf_counter()
        calibrate(rec, "kf_session_r", accelerometer="calibrated")
        out.append(ClosedLoopTiming(name, int(rec.t_s.size), t_cl, time.perf_counter() - t0))
    return out
