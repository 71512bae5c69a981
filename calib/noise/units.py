"""Every identified noise parameter in the units users need (issue 19 item 2).

Conventions (stated in every output):

* **continuous** (what Kalibr's ``imu.yaml`` wants): the white-noise density N with two-sided PSD
  N² — Kalibr's ``*_noise_density`` σ_g, rad/s/√Hz or m/s²/√Hz, discrete σ_d = N/√Δt — and the
  bias random walk K, two-sided PSD of the bias derivative K² — Kalibr's ``*_random_walk`` σ_bg,
  rad/s²/√Hz or m/s³/√Hz, discrete σ_bd = K√Δt (Kalibr wiki "IMU Noise Model"; IEEE Std 952 N, K).
  A **one-sided** density (datasheets often quote it) is √2 times the two-sided one.
* **discrete**: the standard deviation of the term per sample at the recording's rate.
* **datasheet**: °/√h, °/h, °/h/√h, arcsec (gyro); µg/√Hz, µg, µg/√h, m/s (accelerometer).
"""

from __future__ import annotations

import math

from gyrosim.units import G0

__all__ = ["representations", "CONVENTION"]

DEG = math.pi / 180.0
CONVENTION = ("continuous values are two-sided: white-noise PSD N² (Kalibr noise_density = N, per-sample σ = N·√f_s), "
              "bias random-walk PSD K² (Kalibr random_walk = K, per-sample σ = K/√f_s); a one-sided density is √2·N")


def representations(kind: str, field: str, value: float, rate_hz: float, triad: str) -> dict[str, float]:
    """{unit label: value} for one parameter (SI ``value``); gyro units for ``triad == 'gyro'``."""
    gyro = triad == "gyro"
    dt = 1.0 / rate_hz
    if kind == "white_noise":
        out = {"continuous_two_sided (Kalibr noise_density)": value, "one_sided": math.sqrt(2) * value,
               "discrete_sigma_per_sample": value * math.sqrt(rate_hz)}
        out.update({"deg/sqrt(h)": value / DEG * 60.0} if gyro else
                   {"ug/sqrt(Hz) (two-sided)": value / G0 * 1e6, "ug/sqrt(Hz) (one-sided)": math.sqrt(2) * value / G0 * 1e6})
        return out
    if kind == "random_walk":
        out = {"continuous_two_sided (Kalibr random_walk)": value, "discrete_sigma_per_sample": value * math.sqrt(dt)}
        out.update({"deg/h/sqrt(h)": value / DEG * 3600 * 60} if gyro else {"ug/sqrt(h)": value / G0 * 1e6 * 60})
        return out
    if kind == "bias_instability":
        out = {"B": value, "allan_floor_0.664B": 0.664 * value}
        out.update({"deg/h": value / DEG * 3600} if gyro else {"ug": value / G0 * 1e6})
        return out
    if kind == "gauss_markov" and field == "sigma":
        out = {"stationary_sigma": value}
        out.update({"deg/h": value / DEG * 3600} if gyro else {"ug": value / G0 * 1e6})
        return out
    if kind == "gauss_markov" and field == "tau_s":
        return {"s": value, "discrete_phi": math.exp(-dt / value)}
    if kind == "quantization_noise":
        out = {"Q": value, "discrete_sigma_per_sample": math.sqrt(2) * value * rate_hz}
        out.update({"arcsec": value / DEG * 3600} if gyro else {"mm/s": value * 1e3})
        return out
    if kind == "rate_ramp":
        out = {"R": value}
        out.update({"deg/h^2": value / DEG * 3600**2} if gyro else {"ug/h": value / G0 * 1e6 * 3600})
        return out
    return {"si": value}


SI_UNITS = {("white_noise", "gyro"): "rad/s/sqrt(Hz)", ("white_noise", "accelerometer"): "m/s^2/sqrt(Hz)",
            ("random_walk", "gyro"): "rad/s^2/sqrt(Hz)", ("random_walk", "accelerometer"): "m/s^3/sqrt(Hz)",
            ("bias_instability", "gyro"): "rad/s", ("bias_instability", "accelerometer"): "m/s^2",
            ("gauss_markov", "gyro"): "rad/s", ("gauss_markov", "accelerometer"): "m/s^2",
            ("quantization_noise", "gyro"): "rad", ("quantization_noise", "accelerometer"): "m/s",
            ("rate_ramp", "gyro"): "rad/s^2", ("rate_ramp", "accelerometer"): "m/s^3"}


def si_unit(kind: str, field: str, triad: str) -> str:
    return "s" if field == "tau_s" else SI_UNITS.get((kind, triad), "SI")
