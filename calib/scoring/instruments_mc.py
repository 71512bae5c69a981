"""Monte Carlo of the static instruments (north-finding, the tilt-sensor test) against their limits (the score floor:
uses gyrosim to simulate and calib to estimate; nothing below imports it).

* North-finding: one truth per latitude (:func:`gyrosim.northfind.simulate_northfind_truth`),
  many drawn devices; per run the error of ψ̂ against the true heading (wrapped to ±180°), the
  reported σ, and the physical limit σ_ψ of the same procedure with the device's *true* noise
  (:meth:`calib.instruments.northfind.Design.heading_sigma_rad`).  Efficiency = RMS error / limit.
* Tilt test: one truth, many devices; per figure the error of the noisy analysis against the
  same analysis of the noise-free device (:func:`calib.instruments.tilt.figures_of_device`), with the
  reported σ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from gyrosim.northfind import NorthFindSequence, simulate_northfind, simulate_northfind_truth
from gyrosim.sensor_model import SensorModel, stored_sensor_model

from calib.instruments.northfind import find_north
from calib.noise.window_means import noise_terms_from_model

__all__ = ["NorthFindRow", "northfind_monte_carlo"]


@dataclass(frozen=True)
class NorthFindRow:
    """One latitude: RMS heading error, the physical limit, their ratio, and σ's honesty."""

    sensor: str
    latitude_deg: float
    seeds: int
    rms_error_deg: float
    limit_deg: float
    efficiency: float          # RMS error / limit (1 = at the limit)
    mean_error_deg: float
    mean_sigma_deg: float      # mean reported σ_ψ
    z_rms: float               # RMS of error/σ_reported (1 = honest)
    statuses: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def northfind_monte_carlo(sensor: SensorModel, latitudes_deg: list[float], seeds: int, *, first_seed: int = 0,
                          seq: NorthFindSequence | None = None, rate_hz: float = 20.0, heading_deg: float = 30.0,
                          progress: Callable[[], None] | None = None) -> list[NorthFindRow]:
    """North-finding error against the physical limit over ``seeds`` devices at each latitude."""
    seq = seq or NorthFindSequence()
    rows = []
    for j, lat in enumerate(latitudes_deg):
        truth = simulate_northfind_truth(lat, heading_deg, rate_hz, seq=seq)
        true = truth.meta["northfind"]["holds"][0]["truth_heading_deg"]
        err, sig, lim, st = [], [], [], []
        # other devices at each latitude (seeds first + j·seeds …): the latitudes are independent samples
        for s in range(first_seed + j * seeds, first_seed + (j + 1) * seeds):
            rec = simulate_northfind(sensor, lat, truth=truth, seed=s)
            res, design = find_north(rec)
            device = stored_sensor_model(rec.meta)
            st.append(res.status)
            if res.heading_deg is None or design is None:
                continue
            err.append((res.heading_deg - true + 180.0) % 360.0 - 180.0)
            sig.append(res.heading_sigma_deg)
            lim.append(math.degrees(design.heading_sigma_rad(noise_terms_from_model(device, "gyro"))))
            if progress is not None:
                progress()
        e, s_, li = np.array(err), np.array(sig), np.array(lim)
        rms = float(np.sqrt(np.mean(e**2))) if e.size else float("nan")
        limit = float(np.sqrt(np.mean(li**2))) if li.size else float("nan")
        rows.append(
            NorthFindRow(
                sensor.name,
                float(lat),
                seeds,
                rms,
                limit,
                rms / limit,
                float(e.mean()) if e.size else float("nan"),
                float(s_.mean()) if s_.size else float("nan"),
                float(np.sqrt(np.mean((e / s_) ** 2))) if e.size else float("nan"),
                {k: st.count(k) for k in sorted(set(st))},
            )
        )
    return rows


# ---------------------------------------------------------------- tilt test
TILT_FIGURES = ("scale_factor", "nonlinearity_pct_fs", "cross_axis_pct", "cross_axis_horizontal_pct",
                "cross_axis_vertical_pct", "mechanical_zero_deg", "zero_offset_ug", "zero_stability_ug", "zero_std_ug")


@dataclass(frozen=True)
class TiltRow:
    """One figure of one axis over the devices: error of the test against the device's value,
    in units of the reported σ."""

    axis: str
    figure: str
    seeds: int
    device_mean: float        # mean over devices of the figure's true value
    rms_error: float
    mean_error: float
    mean_sigma: float
    z_rms: float
    max_abs_z: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def device_tilt_figures(truth, device: SensorModel, tau_range: dict[str, tuple[float, float]],
                        level_window: tuple[int, int] | None) -> dict[str, dict[str, float | None]]:
    """The figures a noise-free test of ``device`` gives (its deterministic error effects applied
    to the truth; a 1e-12 m/s² white floor keeps the noise fit defined), with the zero stability
    from the device's true noise: the minimum of its Allan model over ``tau_range`` and the
    expected spread of the readings over the level hold.  ``tau_range``: per axis, the τ range
    the test searched (its ``zero_stability_tau_range_s``)."""
    from dataclasses import replace

    from gyrosim.simulate import apply_sensor

    from calib.instruments.tilt import UG, tilt_test
    from calib.noise.allan import FLICKER
    from calib.noise.window_means import expected_sample_variance

    det = replace(device, gyro=(), accelerometer=tuple(e for e in device.accelerometer
                                                       if not e.stochastic and e.stage == "error"))
    clean = apply_sensor(truth, det, np.random.default_rng(0), realize=False)
    clean = clean.with_signals(
        acc_m_s2=clean.acc_m_s2 + 1e-12 * np.random.default_rng(1).standard_normal(clean.acc_m_s2.shape)
    )
    res = tilt_test(clean)
    terms = noise_terms_from_model(device, "accelerometer")
    out = {}
    for s, f in res.axes.items():
        d = {k: getattr(f, k) for k in TILT_FIGURES}
        t = terms["xyz".index(s)]
        lo, hi = tau_range.get(s, (1.0 / truth.rate_hz, 1.0 / truth.rate_hz))
        tau = np.logspace(math.log10(lo), math.log10(hi), 400)
        model = np.sqrt(t.arw**2 / tau + (FLICKER * t.bias_instability) ** 2 + t.rate_random_walk**2 * tau / 3)
        d["zero_stability_ug"] = float(model.min() / UG)
        d["zero_std_ug"] = (math.sqrt(expected_sample_variance(t, level_window, truth.rate_hz, truth.n)) / UG
                            if level_window else None)
        out[s] = d
    return out


def tilt_monte_carlo(sensor: SensorModel, seeds: int, *, first_seed: int = 0, seq=None, rate_hz: float = 10.0,
                     progress: Callable[[], None] | None = None) -> list[TiltRow]:
    """Each figure of ``calib tilt`` against the drawn device's value over ``seeds`` devices (one truth)."""
    from gyrosim.tilttable import simulate_tilt_truth, simulate_tilttable

    from calib.instruments.tilt import tilt_test

    truth = simulate_tilt_truth(rate_hz, seq=seq)
    holds = truth.meta["tilttable"]["holds"]
    level = next(((h["start"], h["stop"]) for h in holds if h["kind"] == "zero"), None)
    acc: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
    for s in range(first_seed, first_seed + seeds):
        rec = simulate_tilttable(sensor, truth=truth, seed=s)
        device = stored_sensor_model(rec.meta)
        res = tilt_test(rec)
        spans = {ax: f.zero_stability_tau_range_s for ax, f in res.axes.items() if f.zero_stability_tau_range_s}
        ref = device_tilt_figures(truth, device, spans, level)
        for ax, f in res.axes.items():
            for name in TILT_FIGURES:
                v, sd, tv = getattr(f, name), getattr(f, f"{name}_sigma", None), ref[ax][name]
                if v is not None and sd and tv is not None:
                    acc.setdefault((ax, name), []).append((v, sd, tv))
        if progress is not None:
            progress()
    rows = []
    for (ax, name), vals in sorted(acc.items()):
        v, sd, tv = (np.array(x) for x in zip(*vals))
        e = v - tv
        z = e / sd
        rows.append(TiltRow(ax, name, len(vals), float(tv.mean()), float(np.sqrt(np.mean(e**2))), float(e.mean()),
                            float(sd.mean()), float(np.sqrt(np.mean(z**2))), float(np.max(np.abs(z)))))
    return rows
