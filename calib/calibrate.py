"""calibrate(): the Zhou 2020 in-self calibration of a recording, end to end.

1. input checks (gaps, units, saturation: :mod:`calib.inputs`);
2. rest detection and the static bias (:mod:`calib.rest`, Zhou §3.2);
3. noise levels: from the recording's stored sensor model when it has one (simulation), else from
   the first rest segment (per-sample σ → density σ/√f_s; hand tremor at rest inflates it, which
   only makes the filter more cautious);  external-acceleration allowance a_ext, unless given:
   the larger of the accelerometer's rest variance beyond its white noise and the whole
   session's  √(3 (⟨(|f| − g)²⟩ − σ_f²)) — |f| − g sees only the component of the external
   acceleration along gravity, a third of an isotropic one's variance.  (Measured: BROAD's slow
   hand rotation has ⟨(|f| − g)²⟩^½ = 0.58 m/s²; with the rest-only allowance the filter
   diverged, NIS 9300.);
4. initial attitude from gravity at rest (roll, pitch; heading is unobservable and set to 0);
5. the 9-state filter (:mod:`calib.kalman`, Zhou §3.3) over the whole recording:
   ``kf`` is the paper's single pass (filterpy); ``iterated`` re-runs the same filter (the
   compiled :mod:`calib.fastkf` kernel) starting from the previous pass's estimates, three passes
   in all.  Each pass relinearises at a better point and the prior's pull vanishes at the fixed
   point (prior centred on the estimate), so the iteration is Gauss–Newton on the batch
   likelihood: the estimator that reaches the Cramér–Rao bound in our Monte Carlo;
6. observability, before the filter runs: the stripped observability matrix of the recording's own
   motion (gyro integrated from the initial attitude; :mod:`calib.observability`) names every
   parameter in its null space (``unobservable: …``); after the filter, a parameter whose
   posterior σ is still above half its prior is named ``weakly observable``.  The normalised
   innovation squared (NIS) of the two attitude rows, averaged over 1 s windows, is compared with
   its χ² band: a filter that leaves the band for long has diverged or is mis-modelled.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from gyrosim.recording import Recording
from gyrosim.rotations import quat_from_two_vectors

from .inputs import check_recording
from .kalman import STATE_NAMES, FilterConfig, FilterHistory, ZhouFilter
from .rest import BiasEstimate, RestSegments, detect_rest, static_bias

__all__ = ["CalibrationResult", "calibrate", "METHODS"]

METHODS = ("kf", "iterated")


@dataclass(frozen=True)
class CalibrationResult:
    """Estimated gyro errors (SI, body frame RFU) with 1σ, and what the run saw."""

    method: str
    bias_rad_s: np.ndarray
    scale_factor: np.ndarray
    nonorthogonality: np.ndarray
    bias_std_rad_s: np.ndarray
    scale_factor_std: np.ndarray
    nonorthogonality_std: np.ndarray
    rest: RestSegments
    config: FilterConfig
    warnings: tuple[str, ...]
    history: FilterHistory = field(repr=False)
    nis_mean: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """The JSON layout of ``calib run --json`` (keys are a promise to users' scripts)."""
        return {
            "method": self.method,
            "gyro": {
                "bias_rad_s": self.bias_rad_s.tolist(),
                "scale_factor": self.scale_factor.tolist(),
                "nonorthogonality": self.nonorthogonality.tolist(),
                "std": {
                    "bias_rad_s": self.bias_std_rad_s.tolist(),
                    "scale_factor": self.scale_factor_std.tolist(),
                    "nonorthogonality": self.nonorthogonality_std.tolist(),
                },
            },
            "rest_segments": self.rest.to_list(),
            "warnings": list(self.warnings),
            "noise": {
                "arw_rad_s_sqrt_hz": self.config.arw_rad_s_sqrt_hz,
                "vrw_m_s2_sqrt_hz": self.config.vrw_m_s2_sqrt_hz,
                "external_acc_allowance_m_s2": self.config.external_acc_allowance_m_s2,
            },
            "consistency": {"nis_mean": self.nis_mean, "nis_expected": 2.0},
            "frames": "body RFU, navigation ENU",
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)


def _sensor_noise_from_meta(rec: Recording) -> tuple[float | None, float | None]:
    raw = rec.meta.get("sensor_model")
    if not raw:
        return None, None
    model = raw if isinstance(raw, dict) else json.loads(raw)
    def density(effs: list[dict]) -> float | None:
        d = [np.mean(e["density"]) for e in effs if e.get("effect") == "white_noise"]
        return float(d[0]) if d else None
    return density(model.get("gyro", [])), density(model.get("accelerometer", []))


@dataclass(frozen=True)
class Prepared:
    """Everything the filter needs from a recording, before the filter runs."""

    bias: BiasEstimate
    rest: RestSegments
    config: FilterConfig
    quat0_nb: np.ndarray
    start: int
    saturated: np.ndarray | None
    warnings: tuple[str, ...]


def prepare(
    rec: Recording,
    *,
    external_acc_allowance_m_s2: float | None = None,
    arw_rad_s_sqrt_hz: float | None = None,
    vrw_m_s2_sqrt_hz: float | None = None,
    min_rest_s: float = 2.0,
) -> Prepared:
    """Steps 1–4 of the module docstring: checks, rest, bias, noise levels, initial attitude."""
    check = check_recording(rec)
    rest = detect_rest(rec)
    bias = static_bias(rec, rest, min_rest_s=min_rest_s)
    a, b = bias.index_range
    fs = rec.rate_hz
    meta_arw, meta_vrw = _sensor_noise_from_meta(rec)
    rest_gyro_sigma = float(np.mean(np.std(rec.gyro_rad_s[a:b], axis=0)))
    rest_acc_sigma = float(np.mean(np.std(rec.acc_m_s2[a:b], axis=0)))
    arw = arw_rad_s_sqrt_hz or meta_arw or rest_gyro_sigma / math.sqrt(fs)
    vrw = vrw_m_s2_sqrt_hz or meta_vrw or rest_acc_sigma / math.sqrt(fs)
    g = float(np.mean(np.linalg.norm(rec.acc_m_s2[a:b], axis=1)))
    if external_acc_allowance_m_s2 is None:
        sigma_f2 = vrw**2 * fs
        rest_excess = rest_acc_sigma**2 - sigma_f2
        along_g = float(np.mean((np.linalg.norm(rec.acc_m_s2[a:], axis=1) - g) ** 2)) - sigma_f2
        external_acc_allowance_m_s2 = math.sqrt(max(rest_excess, 3.0 * along_g, 0.0))
    config = FilterConfig(arw, vrw, external_acc_allowance_m_s2, gravity_m_s2=g)
    q0 = quat_from_two_vectors(rec.acc_m_s2[a:b].mean(axis=0), np.array([0.0, 0.0, 1.0]))  # gravity up, heading 0
    saturated = check.saturated if check.saturated_samples else None
    warnings = list(check.warnings)
    unobs = motion_unobservable(rec, bias.value_rad_s, a)
    if unobs:
        warnings.append(
            f"unobservable: {', '.join(unobs)}: the recording's motion leaves them in the null space of the "
            "stripped observability matrix (Zhou 2020 §4); add rotations about horizontal axes (scale factors) "
            "and about the vertical (non-orthogonality), Zhou 2020 Table 5"
        )
    return Prepared(bias, rest, config, q0, a, saturated, tuple(warnings))


def motion_unobservable(rec: Recording, bias_rad_s: np.ndarray, start: int) -> list[str]:
    """Filter parameters the recording's motion cannot observe (:func:`calib.observability.parameter_gram`).

    Rates and accelerometer averaged over 2 s (calibration rotations live below 1 Hz; gyro noise
    would otherwise put g·σ_ω into every column: 0.85 m/s² per sample for Table 7's reading A),
    sampled at ~10 Hz; null space = less excitation than a 0.01 rad/s rotation gives.
    """
    from .observability import parameter_gram, unobservable_parameters

    step = max(1, int(round(rec.rate_hz / 10.0)))
    win = max(1, int(round(2.0 * rec.rate_hz)))
    kernel = np.ones(win) / win

    def smooth(x: np.ndarray) -> np.ndarray:
        return np.stack([np.convolve(x[:, i], kernel, mode="same") for i in range(3)], axis=1)[::step]

    w = smooth(rec.gyro_rad_s[start:] - bias_rad_s)
    f = smooth(rec.acc_m_s2[start:])
    return unobservable_parameters(parameter_gram(w, f), float(np.median(np.linalg.norm(f, axis=1))))


def calibrate(
    rec: Recording,
    method: str = "kf",
    *,
    external_acc_allowance_m_s2: float | None = None,
    arw_rad_s_sqrt_hz: float | None = None,
    vrw_m_s2_sqrt_hz: float | None = None,
    min_rest_s: float = 2.0,
    iterations: int = 3,
) -> CalibrationResult:
    """Calibrate the gyro of ``rec`` (bias, scale factor, non-orthogonality). ``rec`` is not modified."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    prep = prepare(rec, external_acc_allowance_m_s2=external_acc_allowance_m_s2,
                   arw_rad_s_sqrt_hz=arw_rad_s_sqrt_hz, vrw_m_s2_sqrt_hz=vrw_m_s2_sqrt_hz, min_rest_s=min_rest_s)
    warnings = list(prep.warnings)
    config, a, fs = prep.config, prep.start, rec.rate_hz
    gyro = rec.gyro_rad_s - prep.bias.value_rad_s
    acc = rec.acc_m_s2
    t = rec.t_s
    filt = ZhouFilter(config, prep.quat0_nb, fs)
    if method == "iterated":
        from .fastkf import run_batch

        s0, n0 = None, None
        for _ in range(iterations - 1):
            out = run_batch(gyro[None, a:], acc[None, a:], t[a:], prep.quat0_nb[None], config, fs, scale0=s0, nonortho0=n0)
            s0, n0 = out.scale, out.nonorthogonality
        filt.scale, filt.nonortho = s0[0].copy(), n0[0].copy()
    for k in range(a + 1, rec.n):
        ok = prep.saturated is None or not prep.saturated[k]
        filt.step(float(t[k]), float(t[k] - t[k - 1]), gyro[k - 1], gyro[k], acc[k], update=ok)

    p = np.diag(filt.kf.P)
    std = np.sqrt(p)
    p0 = np.array([config.prior_attitude_rad] * 3 + [config.prior_scale] * 3 + [config.prior_nonorthogonality] * 3)
    named = " ".join(w for w in warnings if w.startswith("unobservable"))
    weak = [STATE_NAMES[i] for i in range(3, 9) if std[i] > 0.5 * p0[i] and STATE_NAMES[i] not in named]
    if weak:
        warnings.append(
            f"weakly observable: {', '.join(weak)} (posterior σ > half the prior): the motion barely excited "
            "them for this noise level; rotate longer or faster about the axes Zhou 2020 Table 5 names"
        )
    nis = np.asarray(filt.history.nis)
    nis = nis[np.isfinite(nis)]
    nis_mean = float(nis.mean()) if nis.size else float("nan")
    win = max(1, int(round(fs)))
    if nis.size >= win:
        means = np.convolve(nis, np.ones(win) / win, mode="valid")[::win]
        hi = stats.chi2.ppf(0.999, 2 * win) / win
        frac = float(np.mean(means > hi))
        if frac > 0.05:
            warnings.append(
                f"divergence: the innovations exceed their 99.9 % χ² bound in {100 * frac:.0f} % of 1 s windows "
                f"(mean NIS {nis_mean:.1f}, expected 2): the filter's noise model does not fit this motion "
                "(external acceleration larger than allowed, or an unmodelled sensor error)"
            )
    return CalibrationResult(
        method=method,
        bias_rad_s=prep.bias.value_rad_s,
        scale_factor=filt.scale.copy(),
        nonorthogonality=filt.nonortho.copy(),
        bias_std_rad_s=prep.bias.std_rad_s,
        scale_factor_std=std[3:6],
        nonorthogonality_std=std[6:9],
        rest=prep.rest,
        config=config,
        warnings=tuple(warnings),
        history=filt.history,
        nis_mean=nis_mean,
    )


def true_gyro_parameters(rec: Recording) -> dict[str, np.ndarray] | None:
    """The simulated device's bias, scale factor and non-orthogonality (SI), if the file has them."""
    raw = rec.meta.get("sensor_model")
    if not raw:
        return None
    model = raw if isinstance(raw, dict) else json.loads(raw)
    out = {"bias_rad_s": np.zeros(3), "scale_factor": np.zeros(3), "nonorthogonality": np.zeros(3)}
    for e in model.get("gyro", []):
        if e["effect"] == "bias":
            out["bias_rad_s"] = out["bias_rad_s"] + np.asarray(e["value"])
        elif e["effect"] == "scale_factor":
            out["scale_factor"] = out["scale_factor"] + np.asarray(e["value"])
        elif e["effect"] == "nonorthogonality":
            out["nonorthogonality"] = out["nonorthogonality"] + np.asarray(e["value"])
    return out
