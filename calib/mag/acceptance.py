"""What the hard-iron regimes do, measured: BROAD's attached-magnet and stationary-magnet trials, a
semi-synthetic stronger magnet, and gyrosim sessions with a magnet switched on mid-session.

* :func:`measured_regime_check` — on a BROAD trial: the calibration's status, exit code, regimes and
  disturbance kinds; the relative spread of |B| (std/mean) over BROAD's ``movement`` samples, raw
  and with each regime's calibration applied on its stretch; BROAD's heading RMSE
  (:func:`gyrosim.attitude_errors.broad_rmse_deg`) of an orientation filter (default VQF 9-axis)
  against the optical reference, raw and calibrated; and, for a trial with an attached regime, the
  same after scaling that regime's offset (its hard iron minus the reference's) ×k — a closer magnet.
* :func:`simulated_regime_check` — gyrosim multiposition sessions (MPU-9250, AK8963) with an
  :class:`gyrosim.effects.AttachedMagnet` switched on at a different time each: the change time's
  error, each regime's hard-iron error over its σ against the simulated device, and |B|'s relative
  spread raw and calibrated (a 1 cm magnet: ``size_ut`` 380, with the board's parts it magnetises
  as ``soft``).

``benchmarks/mag_regimes.py`` writes both as JSON stamped with the commit and command line.
"""

from __future__ import annotations

import math

import numpy as np

from gyrosim.errors import GyrosimError
from gyrosim.recording import Recording

from calib.mag.calibrate import calibrate_magnetometer, true_magnetometer
from calib.mag.result import MagCalibration

__all__ = ["measured_regime_check", "simulated_regime_check", "relative_spread", "heading_rmse_deg",
           "scale_attached_offsets"]


def relative_spread(mag_ut: np.ndarray, mask: np.ndarray) -> float:
    """std/mean of |m| over the samples ``mask`` (dimensionless)."""
    n = np.linalg.norm(np.asarray(mag_ut, dtype=float)[mask], axis=1)
    return float(np.std(n) / np.mean(n))


def heading_rmse_deg(rec: Recording, mag_ut: np.ndarray, estimator: str = "vqf_9d") -> float | None:
    """BROAD's heading RMSE (°) over its ``movement`` samples of ``estimator`` run with the magnetometer
    channel ``mag_ut``; None when the recording has no optical reference or the filter's package is
    missing."""
    from gyrosim.attitude_errors import broad_rmse_deg
    from gyrosim.orientation import load_orientation_estimator, run_orientation

    t = rec.truth
    if t is None or t.quat_nb is None or "movement" not in t.extra:
        return None
    try:
        est = load_orientation_estimator(estimator)
    except GyrosimError:
        return None
    att = run_orientation(est, rec.with_signals(mag_ut=mag_ut), estimator)
    return broad_rmse_deg(att.quat_nb, t.quat_nb, t.extra["movement"] > 0.5)["heading_rmse_deg"]


def scale_attached_offsets(rec: Recording, res: MagCalibration, k: float) -> np.ndarray:
    """The magnetometer channel with every attached regime's offset (its hard iron minus the reference
    regime's, µT) scaled ×k on the regime's stretch: the same magnet, closer."""
    m = np.array(rec.mag_ut, dtype=float)
    ref = res.hard_iron_ut
    last = len(res.regimes) - 1
    for i, r in enumerate(res.regimes):
        if r.kind != "attached" or not r.calibrated:
            continue
        on = (rec.t_s >= r.start_s) & ((rec.t_s < r.end_s) if i < last else (rec.t_s <= r.end_s))
        m[on] += (k - 1.0) * (r.hard_iron_ut - ref)
    return m


def _summary(rec: Recording, res: MagCalibration, movement: np.ndarray, estimator: str) -> dict:
    """Status, regimes, kinds and the two metrics, raw → calibrated, of one calibrated recording."""
    m = np.asarray(rec.mag_ut, dtype=float)
    b = res.compensate(m, rec.t_s)
    return {
        "status": res.status,
        "exit_code": res.exit_code,
        "regimes": [{"start_s": r.start_s, "end_s": r.end_s, "kind": r.kind, "status": r.status, "group": r.group,
                     "hard_iron_uT": r.hard_iron_ut.tolist(), "hard_iron_std_uT": r.hard_iron_std_ut.tolist(),
                     "change_time_s": None if r.change is None else r.change["time_s"],
                     "change_std_s": None if r.change is None else r.change["std_s"]} for r in res.regimes],
        "disturbances": [{"t_start_s": d.t_start_s, "t_end_s": d.t_end_s, "kind": d.kind} for d in res.disturbances],
        "relative_spread_raw": relative_spread(m, movement),
        "relative_spread_calibrated": relative_spread(b, movement),
        "heading_rmse_raw_deg": heading_rmse_deg(rec, m, estimator),
        "heading_rmse_calibrated_deg": heading_rmse_deg(rec, b, estimator),
    }


def measured_regime_check(rec: Recording, *, scales: tuple[float, ...] = (3.0, 5.0), estimator: str = "vqf_9d",
                          method: str = "ellipsoid") -> dict:
    """The module docstring's first check on one recording with BROAD's optical reference."""
    t = rec.truth
    movement = (t.extra["movement"] > 0.5) if t is not None and "movement" in t.extra else np.ones(rec.n, bool)
    res = calibrate_magnetometer(rec, method)
    out = {"estimator": estimator, "method": method, **_summary(rec, res, movement, estimator), "scaled": []}
    if any(r.kind == "attached" for r in res.regimes):
        for k in scales:
            scaled = rec.with_signals(mag_ut=scale_attached_offsets(rec, res, k))
            out["scaled"].append({"scale": k, **_summary(scaled, calibrate_magnetometer(scaled, method), movement,
                                                         estimator)})
    return out


def simulated_regime_check(hands: int = 5, devices: int = 4, *, size_ut: float = 15.0, soft: float = 0.02,
                           schedule: str = "multiposition") -> dict:
    """The module docstring's second check: ``hands`` × ``devices`` sessions (seeded: hand seed h,
    device 1000 + 10 h + d), the magnet (``size_ut`` in a random direction, a ±``soft`` diagonal
    soft iron) attached at 58 + 3.37 d − 2.13 h s."""
    from gyrosim.effects import AttachedMagnet
    from gyrosim.sensor_model import load_sensor
    from gyrosim.simulate import apply_sensor, simulate_truth, with_attached_magnet

    sensor = load_sensor("mpu9250_9axis")
    rows = []
    for hand in range(hands):
        truth = simulate_truth(schedule, "typical", 100.0, seed=hand)
        for dev in range(devices):
            rng = np.random.default_rng(1000 + 10 * hand + dev)
            h = rng.standard_normal(3)
            t_on = round(58.0 + 3.37 * dev - 2.13 * hand, 2)
            magnet = AttachedMagnet(value=h * size_ut / np.linalg.norm(h),
                                    soft_iron=np.diag(rng.uniform(-soft, soft, 3)), t_on_s=t_on)
            rec = apply_sensor(truth, with_attached_magnet(sensor, magnet), rng)
            res = calibrate_magnetometer(rec)
            z = [((r.hard_iron_ut - true_magnetometer(rec, at_s=0.5 * (r.start_s + r.end_s))["hard_iron_uT"])
                  / r.hard_iron_std_ut).tolist() for r in res.regimes]
            times = [r.change["time_s"] for r in res.regimes if r.change]
            m = np.asarray(rec.mag_ut)
            everything = np.ones(rec.n, dtype=bool)
            rows.append({"hand_seed": hand, "device": dev, "t_on_s": t_on, "status": res.status,
                         "regimes": len(res.regimes), "change_times_s": times, "hard_iron_z": z,
                         "relative_spread_raw": relative_spread(m, everything),
                         "relative_spread_calibrated": relative_spread(res.compensate(m, rec.t_s), everything)})
    zs = np.array([v for r in rows for reg in r["hard_iron_z"] for v in reg], dtype=float)
    errs = [abs(r["change_times_s"][0] - r["t_on_s"]) if len(r["change_times_s"]) == 1 else math.inf for r in rows]
    return {"schedule": schedule, "sessions": len(rows), "magnet_uT": size_ut, "magnet_soft_iron": soft,
            "two_regimes": sum(r["regimes"] == 2 for r in rows), "max_change_time_error_s": max(errs),
            "hard_iron_z_values": int(zs.size), "hard_iron_mean_z2": float(np.mean(zs**2)),
            "hard_iron_within_3_sigma": float(np.mean(np.abs(zs) <= 3.0)), "max_abs_z": float(np.max(np.abs(zs))),
            "statuses": sorted({r["status"] for r in rows}),
            "max_relative_spread_calibrated": max(r["relative_spread_calibrated"] for r in rows),
            "min_relative_spread_raw": min(r["relative_spread_raw"] for r in rows), "rows": rows}
