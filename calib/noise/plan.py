"""``calib plan``: how long to record, answered before recording.

* Stochastic parameters: the GMWM sandwich covariance (:mod:`calib.noise.gmwm`) evaluated at the
  preset's own noise model for a record of length T — the identification's own variance, no
  simulation — gives each parameter's relative 1σ, σ(log θ̂)(T); the recording length for a target
  is where that curve crosses it (log–log interpolation on a √2-spaced grid of T).  The 95 %
  interval's relative half-width is ≈ 1.96 σ(log θ̂).
* Deterministic calibration parameters (S, G of the gyro): the Cramér–Rao bound of one pass of
  the schedule (:func:`calib.session.bounds.crlb`, ideal hand, the preset's ARW and VRW); R independent
  repetitions carry R times the information, so R = ⌈(σ₁/σ_target)²⌉.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrosim.effects import Effect

from calib.noise.gmwm import NOISE_TERMS, WaveletModel, canonical_order, sandwich_covariance
from calib.noise.wavelet import WaveletVariance, scales_for, wv_covariance

__all__ = ["noise_terms_of", "predicted_relative_sigma", "record_length", "schedule_repetitions", "PlanRow"]


def noise_terms_of(effects: tuple[Effect, ...], axis: int = 0) -> tuple[tuple[str, ...], np.ndarray]:
    """(kinds, log θ) of a triad's noise terms on one axis (a Gauss–Markov ``bias_instability`` is
    its ``gauss_markov`` process); terms with a zero parameter are left out."""
    terms = []
    for e in effects:
        e = e.noise_model_term()
        if e.kind in NOISE_TERMS:
            vals = [float(np.asarray(getattr(e, f))[axis]) for f in NOISE_TERMS[e.kind].noise_parameters]
            if all(v > 0 for v in vals):
                terms.append((e.kind, vals))
    order = canonical_order(tuple(k for k, _ in terms))
    terms.sort(key=lambda kv: (order.index(kv[0]), kv[1][-1]))
    return tuple(k for k, _ in terms), np.log(np.concatenate([v for _, v in terms]))


def predicted_relative_sigma(kinds: tuple[str, ...], log_params: np.ndarray, rate_hz: float,
                             duration_s: float) -> np.ndarray:
    """σ(log θ̂) of each parameter for a static record of ``duration_s`` at ``rate_hz``."""
    dt = 1.0 / rate_hz
    n = int(round(duration_s * rate_hz))
    m = scales_for(n)
    wv = WaveletVariance(m.astype(float), np.zeros(m.size), n - 2.0 * m + 1, n, dt)
    model = WaveletModel(kinds, wv.m, dt)
    sigma = wv_covariance(model.psd(log_params), wv.m, wv.coefficients)
    cov, _ = sandwich_covariance(kinds, wv, log_params, sigma)
    return np.sqrt(np.clip(np.diag(cov), 0, None))


@dataclass(frozen=True)
class PlanRow:
    """One noise parameter's plan: its value (SI), the target relative 1σ, the shortest static record
    (s) that reaches it, and the predicted relative σ against record length."""

    triad: str
    term: str
    parameter: str
    value_si: float
    target_relative_sigma: float
    record_length_s: float | None    # None: not reached within the search range
    curve_t_s: tuple[float, ...]
    curve_rel_sigma: tuple[float, ...]

    def to_dict(self) -> dict:
        return {"triad": self.triad, "term": self.term, "parameter": self.parameter, "value_si": self.value_si,
                "target_relative_sigma": self.target_relative_sigma, "record_length_s": self.record_length_s,
                "curve": {"t_s": list(self.curve_t_s), "relative_sigma": list(self.curve_rel_sigma)}}


def record_length(effects: tuple[Effect, ...], triad: str, rate_hz: float, target: float,
                  t_range_s: tuple[float, float] = (10.0, 1e6)) -> list[PlanRow]:
    """Per parameter, the shortest static record whose predicted relative 1σ is ≤ ``target``."""
    kinds, logp = noise_terms_of(effects)
    if not kinds:
        return []
    names = WaveletModel(kinds, np.ones(1), 1.0 / rate_hz).names
    ts = np.geomspace(*t_range_s, int(round(2 * math.log2(t_range_s[1] / t_range_s[0]))) + 1)
    ts = ts[ts * rate_hz >= 64]
    curve = []
    for t in ts:
        if scales_for(int(t * rate_hz)).size < len(names) + 2:
            curve.append(np.full(len(names), np.inf))
        else:
            curve.append(predicted_relative_sigma(kinds, logp, rate_hz, float(t)))
    curve = np.array(curve)
    rows = []
    for i, (kind, fld) in enumerate(names):
        c = curve[:, i]
        hit = np.flatnonzero(c <= target)
        length = None
        if hit.size:
            k = int(hit[0])
            if k == 0:
                length = float(ts[0])
            else:  # log–log interpolation between the bracketing T
                a, b = math.log(c[k - 1]), math.log(c[k])
                w = (math.log(target) - a) / (b - a) if np.isfinite(a) and b != a else 1.0
                length = float(math.exp(math.log(ts[k - 1]) + w * (math.log(ts[k]) - math.log(ts[k - 1]))))
        rows.append(PlanRow(triad, kind, fld, float(math.exp(logp[i])), target, length, tuple(ts.tolist()),
                            tuple(np.where(np.isfinite(c), c, -1.0).tolist())))
    return rows


def schedule_repetitions(sensor, schedule: str, rate_hz: float, target_s: float, target_g: float,
                         seed: int = 0) -> dict:
    """Repetitions of ``schedule`` for a target σ on the gyro's S and G (CRLB; module docstring)."""
    from gyrosim.hand import load_hand
    from gyrosim.schedule import load_schedule
    from gyrosim.simulate import simulate_truth

    from calib.session.bounds import crlb
    from calib.session.model import FilterConfig

    def density(effects) -> float:
        return float(sum((np.asarray(e.density) for e in effects if e.is_white_noise), np.zeros(3)).max())

    arw, vrw = density(sensor.gyro), density(sensor.accelerometer)
    if arw <= 0 or vrw <= 0:
        raise ValueError(f"sensor {sensor.name!r} has no white noise on the gyro or the accelerometer: the CRLB "
                         "needs both (it is infinite information otherwise)")
    rec = simulate_truth(load_schedule(schedule), load_hand("ideal"), rate_hz, seed=seed)
    cfg = FilterConfig(arw, vrw)
    p = crlb(rec.truth.omega_body_rad_s, rec.truth.quat_nb, rec.t_s, cfg, rate_hz, np.zeros(3), np.zeros(3))
    truth = rec
    sd = np.sqrt(np.diag(p))
    s1, g1 = float(sd[3:6].max()), float(sd[6:9].max())
    reps = max(math.ceil((s1 / target_s) ** 2), math.ceil((g1 / target_g) ** 2), 1)
    return {"schedule": schedule, "rate_hz": rate_hz, "duration_one_pass_s": float(truth.t_s[-1] - truth.t_s[0]),
            "crlb_one_pass": {"S": sd[3:6].tolist(), "G": sd[6:9].tolist()},
            "target": {"S": target_s, "G": target_g}, "repetitions": reps,
            "crlb_after": {"S": s1 / math.sqrt(reps), "G": g1 / math.sqrt(reps)},
            "assumption": "ideal hand; repetitions add information (independent passes); gyro S and G only"}

