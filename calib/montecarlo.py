"""Monte Carlo of the calibration against the Cramér–Rao bound (the accuracy tables of the docs).

For one schedule, hand and sensor preset: R sessions (seeds), each a device drawn from the preset
with its own noise, calibrated exactly as ``calib run`` does (:func:`calib.calibrate.calibrate`,
methods ``kf`` / ``iterated``, ``--accelerometer estimate`` or ``calibrated``); per parameter the
mean error, RMSE, √CRLB, the efficiency RMSE/√CRLB and the RMS of err/σ (1 when σ is honest);
the paper's Table 8–9 absolute errors beside the gyro's; and the normalised estimation error
squared (NEES) against its χ² band, over the 6 gyro filter parameters (S, G) and over all
parameters the calibration reports (gyro b, S, G and, when estimated, the accelerometer's).

* The ideal hand's motion is deterministic, so its MuJoCo truth is simulated once and only the
  sensor differs between seeds; other hands simulate a session per seed.
* ``calibrated_accelerometer``: keep only the accelerometer's white noise, as Zhou §3.3.2 assumes
  ("the accelerometer has been well calibrated"); with the raw MPU-9250 accelerometer and
  ``accelerometer="calibrated"`` the gravity reference is tilted by up to 3.5° and the result is
  flagged (status ``inconsistent``).
* CRLB: :func:`calib.fastkf.crlb_joint` at the truth trajectory of the first seed and the first
  device, with the noise levels the calibration estimated (all three measurement rows: the bound
  of the full model); for the static bias σ²/n of the rest average.  With the accelerometer
  calibrated the layout is the paper's and the bias is the static average.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
from scipy import stats

from gyrosim.calibration import truth_calibration
from gyrosim.hand import load_hand
from gyrosim.rotations import quat_conjugate, quat_rotate
from gyrosim.schedule import load_schedule
from gyrosim.sensor_model import load_sensor
from gyrosim.simulate import apply_sensor, simulate_truth

from .calibrate import calibrate
from .fastkf import crlb_joint
from .kalman import JOINT, PAPER, FilterConfig

__all__ = ["MonteCarloResult", "MethodStats", "monte_carlo", "PAPER_ABS_ERROR", "PARAMS"]

GYRO_PARAMS = ("bias_x", "bias_y", "bias_z", "S_x", "S_y", "S_z", "G_x", "G_y", "G_z")
ACC_PARAMS = ("acc_b_x", "acc_b_y", "acc_b_z", "acc_S_x", "acc_S_y", "acc_S_z", "acc_G_x", "acc_G_y", "acc_G_z")
PARAMS = GYRO_PARAMS
# Zhou 2020 Table 8 (bias, °/s → rad/s) and Table 9 (S, G): absolute errors of their one run
PAPER_ABS_ERROR = np.array([math.radians(0.05), math.radians(0.04), math.radians(0.06),
                            0.00196, 0.0005, 0.0011, 0.0017, 0.0002, 0.0004])


@dataclass(frozen=True)
class MethodStats:
    """Per-parameter statistics of one method over the seeds (SI: rad/s and m/s² for biases)."""

    mean_error: np.ndarray
    rmse: np.ndarray
    efficiency: np.ndarray
    nees_mean: float
    nees_band: tuple[float, float]
    z_rms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nees_all_mean: float = float("nan")
    nees_all_band: tuple[float, float] = (float("nan"), float("nan"))
    statuses: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class MonteCarloResult:
    schedule: str
    hand: str
    sensor: str
    seeds: int
    truth_mean: np.ndarray
    sqrt_crlb: np.ndarray
    methods: dict[str, MethodStats] = field(default_factory=dict)
    accelerometer: str = "calibrated"
    names: tuple[str, ...] = GYRO_PARAMS

    def table(self) -> str:
        """A plain-text table (gyro bias in °/s, accelerometer bias in mg)."""
        scale = np.array([180 / math.pi] * 3 + [1.0] * 6 + ([1000 / 9.80665] * 3 + [1.0] * 6 if len(self.names) > 9 else []))
        head = f"{'param':<9} {'true':>9} {'√CRLB':>9} " + " ".join(
            f"{m + ' mean err':>13} {m + ' RMSE':>10} {m + ' eff.':>8} {m + ' z RMS':>9}" for m in self.methods) + \
            f" {'paper |err|':>11}"
        rows = [f"Monte Carlo: {self.schedule}, hand {self.hand}, sensor {self.sensor}, accelerometer {self.accelerometer}, "
                f"{self.seeds} seeds (gyro bias °/s, accelerometer bias mg; efficiency = RMSE/√CRLB; z = err/σ)", head]
        for i, name in enumerate(self.names):
            cells = [f"{name:<9} {self.truth_mean[i] * scale[i]:>9.5f} {self.sqrt_crlb[i] * scale[i]:>9.5f}"]
            for st in self.methods.values():
                cells.append(f"{st.mean_error[i] * scale[i]:>13.5f} {st.rmse[i] * scale[i]:>10.5f} {st.efficiency[i]:>8.2f} "
                             f"{st.z_rms[i]:>9.2f}")
            cells.append(f"{PAPER_ABS_ERROR[i] * scale[i]:>11.5f}" if i < 9 else f"{'':>11}")
            rows.append(" ".join(cells))
        for m, st in self.methods.items():
            rows.append(f"NEES ({m}, 6 gyro filter parameters): mean {st.nees_mean:.2f}, 95 % band "
                        f"[{st.nees_band[0]:.2f}, {st.nees_band[1]:.2f}]; all {len(self.names)} parameters: mean "
                        f"{st.nees_all_mean:.2f}, band [{st.nees_all_band[0]:.2f}, {st.nees_all_band[1]:.2f}]; status "
                        + ", ".join(f"{k} {v}" for k, v in sorted(st.statuses.items())))
        return "\n".join(rows)

    def to_dict(self) -> dict:
        return {"schedule": self.schedule, "hand": self.hand, "sensor": self.sensor, "seeds": self.seeds,
                "accelerometer": self.accelerometer, "parameters": list(self.names),
                "truth_mean": self.truth_mean.tolist(), "sqrt_crlb": self.sqrt_crlb.tolist(),
                "methods": {m: {"mean_error": st.mean_error.tolist(), "rmse": st.rmse.tolist(),
                                "efficiency": st.efficiency.tolist(), "z_rms": st.z_rms.tolist(),
                                "nees_mean": st.nees_mean, "nees_band": list(st.nees_band),
                                "nees_all_mean": st.nees_all_mean, "nees_all_band": list(st.nees_all_band),
                                "statuses": st.statuses} for m, st in self.methods.items()}}


def _stats(est: np.ndarray, cov: np.ndarray, truth: np.ndarray, sqrt_crlb: np.ndarray, statuses: list[str],
           filter_cols: slice) -> MethodStats:
    err = est - truth
    n, p = err.shape
    rmse = np.sqrt(np.mean(err**2, axis=0))
    sd = np.sqrt(np.einsum("bii->bi", cov))
    z = err / sd
    e6 = err[:, filter_cols]
    c6 = cov[:, filter_cols, filter_cols]
    nees6 = np.einsum("bi,bij,bj->b", e6, np.linalg.inv(c6), e6)
    nees = np.einsum("bi,bij,bj->b", err, np.linalg.inv(cov), err)
    k6 = e6.shape[1]
    band6 = (stats.chi2.ppf(0.025, k6 * n) / n, stats.chi2.ppf(0.975, k6 * n) / n)
    band = (stats.chi2.ppf(0.025, p * n) / n, stats.chi2.ppf(0.975, p * n) / n)
    counts: dict[str, int] = {}
    for s in statuses:
        counts[s] = counts.get(s, 0) + 1
    return MethodStats(err.mean(axis=0), rmse, rmse / sqrt_crlb, float(nees6.mean()), band6,
                       np.sqrt(np.mean(z**2, axis=0)), float(nees.mean()), band, counts)


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
    accelerometer: str = "calibrated",
) -> MonteCarloResult:
    """Run the Monte Carlo (module docstring) and return its statistics."""
    sched, hnd, model = load_schedule(schedule), load_hand(hand), load_sensor(sensor)
    if calibrated_accelerometer:
        model = replace(model, name=f"{model.name} (accelerometer calibrated)",
                        accelerometer=tuple(e for e in model.accelerometer if e.kind == "white_noise"))
    estimate = accelerometer == "estimate"
    names = GYRO_PARAMS + (ACC_PARAMS if estimate else ())
    truth_fixed = simulate_truth(sched, hnd, rate_hz, seed=first_seed) if hnd.is_ideal else None
    est = {m: [] for m in methods}
    cov = {m: [] for m in methods}
    status = {m: [] for m in methods}
    truths = []
    first = None
    for k in range(seeds):
        seed = first_seed + k
        truth = truth_fixed if truth_fixed is not None else simulate_truth(sched, hnd, rate_hz, seed=seed)
        rec = apply_sensor(truth, model, np.random.default_rng(10_000 + seed))
        tc = truth_calibration(rec)
        truths.append(np.concatenate([tc.vector("gyro")] + ([tc.vector("accelerometer")] if estimate else [])))
        for m in methods:
            c = calibrate(rec, m, accelerometer=accelerometer, keep_history=False)
            items = [("gyro", "bias"), ("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
            if estimate:
                items += [("accelerometer", "bias"), ("accelerometer", "scale_factor"), ("accelerometer", "nonorthogonality")]
            est[m].append(np.concatenate([c.value(t, kd) for t, kd in items]))
            cov[m].append(c.block_covariance(items))
            status[m].append(c.status)
            if first is None:
                first = (rec, c)
        if progress is not None:
            progress(1)
    truths_arr = np.stack(truths)
    rec0, c0 = first
    noise = c0.diagnostics["noise"]
    config = FilterConfig(noise["arw_rad_s_sqrt_hz"], noise["vrw_m_s2_sqrt_hz"], noise["external_acc_allowance_m_s2"],
                          gravity_m_s2=noise["gravity_m_s2"])
    tr = rec0.truth
    start = int(round((c0.diagnostics["filter"]["start_s"] - rec0.t_s[0]) * rate_hz))
    f_g = quat_rotate(quat_conjugate(tr.quat_nb[start:]), np.array([0.0, 0.0, config.gravity_m_s2]))
    th = np.zeros(18)
    th[0:3], th[3:6], th[6:9] = truths_arr[0, 3:6], truths_arr[0, 6:9], truths_arr[0, 0:3]
    if estimate:
        th[9:12], th[12:15], th[15:18] = truths_arr[0, 9:12], truths_arr[0, 12:15], truths_arr[0, 15:18]
    layout = JOINT if estimate else PAPER
    p = crlb_joint(tr.omega_body_rad_s[start:], f_g, tr.quat_nb[start:], rec0.t_s[start:], th, layout, config, rate_hz)
    a, b = (int(round(x * rate_hz)) for x in c0.diagnostics["rest_segments"][0])
    bias_crlb = np.full(3, config.arw_rad_s_sqrt_hz * math.sqrt(rate_hz) / math.sqrt(max(b - a, 1)))
    sd = np.sqrt(np.diag(p))
    crlb = [bias_crlb if not estimate else sd[9:12], sd[3:9]]
    if estimate:
        crlb.append(sd[12:21])
    sqrt_crlb = np.concatenate(crlb)
    result = {m: _stats(np.stack(est[m]), np.stack(cov[m]), truths_arr, sqrt_crlb, status[m], slice(3, 9))
              for m in methods}
    return MonteCarloResult(schedule, hand, model.name, seeds, truths_arr.mean(axis=0), sqrt_crlb, result,
                            accelerometer, names)
