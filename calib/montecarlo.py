"""Monte Carlo of the calibration against the Cramér–Rao bound (issue 4's accuracy table).

For one schedule, hand and sensor preset: R sessions (seeds), each a device drawn from the preset
with its own noise, calibrated by every method; per parameter the mean error, RMSE, √CRLB and the
efficiency RMSE/√CRLB, next to the paper's Table 8–9 absolute errors; and the normalised
estimation error squared (NEES) of the 6 filter parameters against its χ² band.

* The ideal hand's motion is deterministic, so its MuJoCo truth is simulated once and only the
  sensor differs between seeds; other hands simulate a session per seed.
* All R filters run at once in the compiled kernel (:func:`calib.fastkf.run_batch`), which equals
  the filterpy filter to rounding; ``kf`` is its single pass, ``iterated`` three passes.
* ``calibrated_accelerometer``: keep only the accelerometer's white noise, as Zhou §3.3.2 assumes
  ("the accelerometer has been well calibrated"); a raw MPU-9250 accelerometer (±60 mg bias)
  tilts the gravity reference by up to 3.5° and the filter diverges (and says so).
* CRLB: :func:`calib.fastkf.crlb` at the truth trajectory of the first seed with the mean true
  S, G; for the bias, σ²/n of the rest average (white noise σ = N √f_s over n rest samples).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
from scipy import stats

from gyrosim.hand import load_hand
from gyrosim.schedule import load_schedule
from gyrosim.sensor_model import load_sensor
from gyrosim.simulate import apply_sensor, simulate_truth

from .calibrate import prepare, true_gyro_parameters
from .fastkf import crlb, run_batch
from .kalman import FilterConfig

__all__ = ["MonteCarloResult", "monte_carlo", "PAPER_ABS_ERROR"]

PARAMS = ("bias_x", "bias_y", "bias_z", "S_x", "S_y", "S_z", "G_x", "G_y", "G_z")
# Zhou 2020 Table 8 (bias, °/s → rad/s) and Table 9 (S, G): absolute errors of their one run
PAPER_ABS_ERROR = np.array([math.radians(0.05), math.radians(0.04), math.radians(0.06),
                            0.00196, 0.0005, 0.0011, 0.0017, 0.0002, 0.0004])


@dataclass(frozen=True)
class MethodStats:
    """Per-parameter statistics of one method over the seeds (SI: rad/s for bias, 1 for S, G)."""

    mean_error: np.ndarray
    rmse: np.ndarray
    efficiency: np.ndarray
    nees_mean: float
    nees_band: tuple[float, float]


@dataclass(frozen=True)
class MonteCarloResult:
    schedule: str
    hand: str
    sensor: str
    seeds: int
    truth_mean: np.ndarray
    sqrt_crlb: np.ndarray
    methods: dict[str, MethodStats] = field(default_factory=dict)

    def table(self) -> str:
        """A plain-text table (bias in °/s)."""
        scale = np.array([180 / math.pi] * 3 + [1.0] * 6)
        head = f"{'param':<7} {'true':>9} {'√CRLB':>9} " + " ".join(
            f"{m + ' mean err':>13} {m + ' RMSE':>10} {m + ' eff.':>8}" for m in self.methods) + f" {'paper |err|':>11}"
        rows = [f"Monte Carlo: {self.schedule}, hand {self.hand}, sensor {self.sensor}, {self.seeds} seeds "
                "(bias in °/s; efficiency = RMSE/√CRLB)", head]
        for i, name in enumerate(PARAMS):
            cells = [f"{name:<7} {self.truth_mean[i] * scale[i]:>9.5f} {self.sqrt_crlb[i] * scale[i]:>9.5f}"]
            for st in self.methods.values():
                cells.append(f"{st.mean_error[i] * scale[i]:>13.5f} {st.rmse[i] * scale[i]:>10.5f} {st.efficiency[i]:>8.2f}")
            cells.append(f"{PAPER_ABS_ERROR[i] * scale[i]:>11.5f}")
            rows.append(" ".join(cells))
        for m, st in self.methods.items():
            rows.append(f"NEES ({m}, 6 filter parameters): mean {st.nees_mean:.2f}, 95 % band "
                        f"[{st.nees_band[0]:.2f}, {st.nees_band[1]:.2f}]")
        return "\n".join(rows)


def monte_carlo(
    schedule: str = "zhou2020",
    hand: str = "ideal",
    sensor: str = "zhou2020_sim",
    seeds: int = 50,
    rate_hz: float = 100.0,
    methods: tuple[str, ...] = ("kf", "iterated"),
    first_seed: int = 0,
    progress: Callable[[int], None] | None = None,
    calibrated_accelerometer: bool = False,
) -> MonteCarloResult:
    """Run the Monte Carlo (module docstring) and return its statistics."""
    sched, hnd, model = load_schedule(schedule), load_hand(hand), load_sensor(sensor)
    if calibrated_accelerometer:
        model = replace(model, name=f"{model.name} (accelerometer calibrated)",
                        accelerometer=tuple(e for e in model.accelerometer if e.kind == "white_noise"))
    truth_fixed = simulate_truth(sched, hnd, rate_hz, seed=first_seed) if hnd.is_ideal else None
    gyro, acc, q0, truths, preps, truth_recs = [], [], [], [], [], []
    for k in range(seeds):
        seed = first_seed + k
        truth = truth_fixed if truth_fixed is not None else simulate_truth(sched, hnd, rate_hz, seed=seed)
        rec = apply_sensor(truth, model, np.random.default_rng(10_000 + seed))
        prep = prepare(rec)
        gyro.append(rec.gyro_rad_s - prep.bias.value_rad_s)
        acc.append(rec.acc_m_s2)
        q0.append(prep.quat0_nb)
        tp = true_gyro_parameters(rec)
        truths.append(np.concatenate([tp["bias_rad_s"], tp["scale_factor"], tp["nonorthogonality"]]))
        preps.append(prep)
        truth_recs.append(rec)
        if progress is not None:
            progress(1)
    start = max(p.start for p in preps)  # batched filters share one start: the latest rest start
    t = truth_recs[0].t_s[start:]
    g_arr, a_arr, q_arr = np.stack(gyro)[:, start:], np.stack(acc)[:, start:], np.stack(q0)
    truths_arr = np.stack(truths)
    c0 = preps[0].config
    config = FilterConfig(c0.arw_rad_s_sqrt_hz, c0.vrw_m_s2_sqrt_hz,
                          float(np.mean([p.config.external_acc_allowance_m_s2 for p in preps])),
                          gravity_m_s2=float(np.mean([p.config.gravity_m_s2 for p in preps])))
    bias_est = np.stack([p.bias.value_rad_s for p in preps])

    # CRLB at the truth trajectory (first seed), mean true S and G
    tr = truth_recs[0].truth
    p_crlb = crlb(tr.omega_body_rad_s[start:], tr.quat_nb[start:], t, config, rate_hz, truths_arr[:, 3:6].mean(0), truths_arr[:, 6:9].mean(0))
    a, b = preps[0].bias.index_range
    bias_crlb = np.full(3, config.arw_rad_s_sqrt_hz * math.sqrt(rate_hz) / math.sqrt(b - a))
    sqrt_crlb = np.concatenate([bias_crlb, np.sqrt(np.diag(p_crlb))[3:9]])

    result_methods: dict[str, MethodStats] = {}
    s0 = n0 = None
    passes = {"kf": 1, "iterated": 3}
    done = 0
    for method in sorted(methods, key=lambda m: passes[m]):
        while done < passes[method]:
            out = run_batch(g_arr, a_arr, t, q_arr, config, rate_hz, scale0=s0, nonortho0=n0)
            s0, n0 = out.scale, out.nonorthogonality
            done += 1
        est = np.concatenate([bias_est, out.scale, out.nonorthogonality], axis=1)
        err = est - truths_arr
        rmse = np.sqrt(np.mean(err**2, axis=0))
        e6 = err[:, 3:9]
        p6 = out.p[:, 3:9, 3:9]
        nees = np.einsum("bi,bij,bj->b", e6, np.linalg.inv(p6), e6)
        band = (stats.chi2.ppf(0.025, 6 * seeds) / seeds, stats.chi2.ppf(0.975, 6 * seeds) / seeds)
        result_methods[method] = MethodStats(err.mean(axis=0), rmse, rmse / sqrt_crlb, float(nees.mean()), band)
    return MonteCarloResult(schedule, hand, model.name, seeds, truths_arr.mean(axis=0), sqrt_crlb, result_methods)
