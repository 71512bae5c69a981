"""The model loop (issue 5): fit the declared model, find what its residual lacks, add it, repeat.

1. Reference (:func:`~calib.closeloop.reference.build_reference`): truth rate > optical
   orientation > at rest (zero rate) | gravity self-consistency.
2. Declared model: the vocabulary effects the user names (default bias, scale factor,
   non-orthogonality: Zhou 2020 eq. 1), fitted by least squares against the reference.
3. Every other gyro effect of the vocabulary is a candidate; each is scored by its held-out
   information gain G (:mod:`calib.closeloop.fit`): fitted on the even held-out groups (4 s
   stretches by default), scored on the odd ones, penalised by BIC for the parameters it adds.
4. The candidate with the largest G > 0 joins the model; repeat until no candidate has G > 0.
   Bias drift (a spline in time) can mimic any slow term, so it is chosen only in a round where
   no candidate tied to a measured channel (temperature, specific force, field, rate) has G > 0.
   A runner-up whose G is within the winner's own penalty of it is reported as *not
   distinguished* from the winner (both explain the same residual on this recording).
5. What remains is tested for structure no candidate explains (:mod:`calib.closeloop.structure`).

Errors are reported on held-out rows only (the model fitted on the fit rows).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np

from gyrosim.effects import EFFECTS, RandomWalk, TimeOffset
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.rotations import quat_angle_between
from gyrosim.strapdown import integrate_gyro
from gyrosim.units import G0

from ..inputs import check_recording
from ..timeblocks import block_means, time_block_index
from .candidates import Candidate, build_candidate, candidate_kinds, earth_rate_summary
from .drift import random_walk_mle
from .fit import FitResult, fit_model, held_out_score, held_out_split
from .reference import GravityReference, RateReference, Reference, build_reference
from .structure import channel_correlations, spectral_lines, variance_growth, whiteness

__all__ = ["Finding", "CloseloopResult", "run_closeloop", "DEFAULT_DECLARED"]

DEFAULT_DECLARED = ("bias", "scale_factor", "nonorthogonality")
_DIMENSIONLESS = ("scale_factor", "nonorthogonality", "misalignment")
CATCH_ALL = ("random_walk",)  # chosen only when no candidate tied to a measured channel is worth adding
DEG = 180.0 / math.pi


@dataclass(frozen=True)
class Finding:
    """One effect the loop added: its fitted parameters (SI, with 1σ) and the evidence for it."""

    effect: str
    params: dict[str, dict[str, float]]
    model: dict                      # the effect as gyrosim serialises it (SI): inject it with effect_from_dict
    evidence: dict
    trace: str


@dataclass
class CloseloopResult:
    reference: str
    reference_description: str
    notes: list[str]
    declared: list[str]
    declared_params: dict[str, dict[str, float]]
    found: list[Finding]
    unexplained: dict
    not_tested: dict[str, str]
    not_distinguished: list[dict]
    error_before: dict[str, float]
    error_after: dict[str, float]
    checks: dict
    rounds: list[list[dict]]
    row_time_s: np.ndarray = field(repr=False, default=None)
    row_axis: np.ndarray = field(repr=False, default=None)
    held_out_rows: np.ndarray = field(repr=False, default=None)
    residual_before: np.ndarray = field(repr=False, default=None)
    residual_after: np.ndarray = field(repr=False, default=None)
    follows_series: dict = field(repr=False, default_factory=dict)
    rows_of: Callable | None = field(repr=False, default=None)   # per-sample (N, 3) → residual rows

    def to_json_dict(self) -> dict:
        return {
            "reference": self.reference, "reference_description": self.reference_description, "notes": self.notes,
            "declared": self.declared, "declared_params": self.declared_params,
            "found": [asdict(f) for f in self.found], "unexplained": self.unexplained,
            "not_tested": self.not_tested, "not_distinguished": self.not_distinguished,
            "error_before": self.error_before, "error_after": self.error_after, "checks": self.checks,
            "rounds": self.rounds,
        }


def _bounds(cands: list[Candidate]) -> tuple[np.ndarray, np.ndarray]:
    lo = [c.bounds()[0] for c in cands]
    hi = [c.bounds()[1] for c in cands]
    return (np.concatenate(lo), np.concatenate(hi)) if cands else (np.zeros(0), np.zeros(0))


def _stack(cands: list[Candidate], n: int) -> np.ndarray:
    return np.concatenate([c.regressors for c in cands], axis=2) if cands else np.zeros((n, 3, 0))


def _params(cands: list[Candidate], fit: FitResult) -> list[dict[str, dict[str, float]]]:
    out, i = [], 0
    sig = np.sqrt(np.maximum(np.diag(fit.cov), 0.0))
    for c in cands:
        out.append({name: {"value": float(fit.theta[i + j]), "sigma": float(sig[i + j])}
                    for j, name in enumerate(c.param_names)})
        i += c.n_params
    return out


def _theta_of(cands: list[Candidate], theta: np.ndarray, kind: str) -> np.ndarray:
    i = 0
    for c in cands:
        if c.effect == kind:
            return theta[i : i + c.n_params]
        i += c.n_params
    raise KeyError(kind)


def _quantization(y: np.ndarray) -> dict:
    out = {}
    for a, name in enumerate("xyz"):
        u = np.unique(y[:, a])
        if u.size < 3 or u.size > y.shape[0] // 2:
            out[name] = None
            continue
        lsb = float(np.min(np.diff(u)))
        k = y[:, a] / lsb
        out[name] = lsb if float(np.sqrt(np.mean((k - np.round(k)) ** 2))) < 0.01 else None
    return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _summary(kind: str, values: np.ndarray, sigmas: np.ndarray) -> str:
    if kind == "time_offset":
        d, s = values[0], sigmas[0]
        fc = 1 / (2 * math.pi * abs(d)) if d else math.inf
        return f"time offset of {d * 1e3:.2f} ± {s * 1e3:.2f} ms (≡ first-order bandwidth {fc:.0f} Hz)"
    if kind == "earth_rate":
        e = earth_rate_summary(values)
        return f"a rate fixed in ENU: latitude {e['latitude_deg']:.1f}°, |ω| = {e['magnitude_over_wgs84']:.2f} × Earth rate"
    if kind == "random_walk":
        return f"bias drift: knot biases RMS {np.std(values) * DEG:.4f} °/s"
    unit = {"g_sensitivity": (DEG * G0, "°/s/g"), "temperature_bias": (DEG, "°/s/°C"),
            "temperature_scale": (1e6, "ppm/°C"), "misalignment": (1e3, "mrad"),
            "scale_nonlinearity": (1.0, "1/(rad/s)"), "magnetic_sensitivity": (DEG * 3600, "°/h/µT"),
            "thermal_hysteresis": (DEG, "(°/s)/(°C/s)"), "bias": (DEG, "°/s"), "scale_factor": (1e6, "ppm"),
            "nonorthogonality": (1e3, "mrad")}.get(kind, (1.0, "SI"))
    vals = ", ".join(f"{v * unit[0]:.3g}±{s * unit[0]:.2g}" for v, s in zip(values, sigmas))
    return f"{kind} [{vals}] {unit[1]}"


def _attitude_rms(ref: Reference, rec: Recording, corrected: np.ndarray) -> float | None:
    """Strapdown orientation error RMS (°) over the movement phase (BROAD's definition: the
    ``movement`` mask; else the whole record), integrated from its first sample with the reference
    orientation there."""
    tr = rec.truth
    if tr is None or tr.quat_nb is None:
        return None
    q_ref = np.asarray(tr.quat_nb)
    move = tr.extra.get("movement")
    mask = np.asarray(move, bool) if move is not None else np.ones(rec.t_s.size, bool)
    idx = np.flatnonzero(mask)
    a, b = int(idx[0]), int(idx[-1]) + 1
    start = a + int(np.argmax(np.all(np.isfinite(q_ref[a:b]), axis=1)))
    q = integrate_gyro(rec.t_s[start:b], corrected[start:b], q_ref[start])
    err = quat_angle_between(q, q_ref[start:b])
    ok = mask[start:b] & np.isfinite(err)
    return float(np.sqrt(np.mean(err[ok] ** 2)) * DEG)


def _channels(ref: RateReference, rec: Recording) -> dict[str, np.ndarray]:
    ctx = ref.ctx
    per = {f"gyro_{a}": rec.gyro_rad_s[:, i] for i, a in enumerate("xyz")}
    per.update({f"acc_{a}": rec.acc_m_s2[:, i] for i, a in enumerate("xyz")})
    per["|f| - g"] = np.linalg.norm(rec.acc_m_s2, axis=1) - G0
    per["|omega|"] = np.linalg.norm(ctx.omega_true_rad_s, axis=1)
    dw = np.gradient(ctx.omega_true_rad_s, ctx.t_s, axis=0)
    per.update({f"domega_{a}/dt": dw[:, i] for i, a in enumerate("xyz")})
    if rec.temp_c is not None:
        per["temperature"] = rec.temp_c
        per["dT/dt"] = np.gradient(rec.temp_c, rec.t_s)
    if ctx.mag_body_ut is not None:
        per.update({f"mag_{a}": ctx.mag_body_ut[:, i] for i, a in enumerate("xyz")})
    per["time"] = rec.t_s
    out = {}
    for k, v in per.items():
        b = ref.rows_of(np.repeat(np.asarray(v, float)[:, None], 3, axis=1)).reshape(-1, 3)[:, 0]
        if np.ptp(b) > 0:
            out[k] = b
    return out


def run_closeloop(
    rec: Recording,
    declared: tuple[str, ...] | list[str] = DEFAULT_DECLARED,
    *,
    reference: str | None = None,
    holdout_s: float = 4.0,
    candidates: list[str] | None = None,
    max_rounds: int = 6,
    drift_knot_s: float = 20.0,
    progress: Callable[[str], None] | None = None,
) -> CloseloopResult:
    """Run the loop on a recording (the input is not modified); see the module docstring."""
    declared = list(declared)
    unknown = [k for k in declared if k not in EFFECTS]
    if unknown:
        raise RecordingError(f"--declared: unknown effect(s) {unknown}; the vocabulary has {', '.join(EFFECTS)}")
    check = check_recording(rec, allow_gaps=True)
    try:  # saturated samples carry no information about the rate: their rows are left out
        ref = build_reference(rec, holdout_s=holdout_s, prefer=reference, exclude=check.saturated)
    except RecordingError as err:
        if "rest poses" not in str(err):
            raise
        return _no_reference(rec, declared, str(err), check)
    n = rec.t_s.size
    say = progress or (lambda s: None)

    model: list[Candidate] = []
    not_tested: dict[str, str] = {}
    for kind in declared:
        c = build_candidate(kind, ref.ctx, drift_knot_s=drift_knot_s)
        if isinstance(c, str):
            raise RecordingError(f"declared effect {kind!r} cannot be fitted here: {c}")
        model.append(c)
    pool: dict[str, Candidate] = {}
    for kind in candidates or candidate_kinds():
        if kind in declared:
            continue
        c = build_candidate(kind, ref.ctx, drift_knot_s=drift_knot_s)
        if isinstance(c, str):
            not_tested[kind] = c
        else:
            pool[kind] = c
    if ref.kind == "static":
        for kind in ("scale_factor", "nonorthogonality", "misalignment", "scale_nonlinearity", "time_offset"):
            if kind in pool:
                not_tested[kind] = "the recording is at rest: a rate-proportional term has no excitation"
                pool.pop(kind)

    fit_rows, held = held_out_split(ref)
    if held.sum() < 3 or fit_rows.sum() < 3:
        raise RecordingError(
            f"the recording is too short for a held-out split: {fit_rows.sum()} fit and {held.sum()} held-out rows "
            f"with {holdout_s:g} s held-out groups; record longer or pass a shorter --holdout")
    declared_fit = fit_model(ref, _stack(model, n), fit_rows, bounds=_bounds(model))
    if isinstance(ref, GravityReference):
        ref.reweight(declared_fit.residual)
        declared_fit = fit_model(ref, _stack(model, n), fit_rows, theta0=declared_fit.theta, bounds=_bounds(model))
    p_decl = sum(c.n_params for c in model)
    notes = list(ref.notes) + list(check.warnings)
    if declared_fit.rank < p_decl:
        notes.append(f"the declared model has {p_decl} parameters but the recording identifies only "
                     f"{declared_fit.rank}: the motion does not excite all of them")

    delay = {"total_s": 0.0}
    y_measured = np.asarray(rec.gyro_rad_s)

    def refresh_output_stage(fit: FitResult) -> FitResult:
        """Time offset, fitted exactly: the linear regressor −ẋ leaves ½d²ẍ, which at hand-tremor
        frequencies (8–12 Hz, 2πf·d ≈ 0.2 rad for 3.4 ms) biased d̂ by 1 % and the scale factor by
        2e-4 in a noise-free test.  So the delay found so far is undone on the measured gyro (the
        Fourier shift of the vocabulary's TimeOffset.inverse, exact), and the model keeps only the
        small remaining δd, linear around it; three passes converge to rounding.  The regressor
        is evaluated on the error-stage output (I + S + N) ω + b, which is what the output stage delays."""
        idx = [i for i, c in enumerate(model) if c.effect == "time_offset"]
        for _ in range(3 if idx and isinstance(ref, RateReference) else 1):
            if idx and isinstance(ref, RateReference):
                j = sum(c.n_params for c in model[: idx[0]])
                delay["total_s"] += float(fit.theta[j])
                ref.y_rad_s = TimeOffset(delay_s=delay["total_s"]).inverse(y_measured, ref.ctx)
            rate = _error_stage_rate(ref, model, fit.theta)
            if "time_offset" in pool:
                pool["time_offset"] = build_candidate("time_offset", ref.ctx, modelled_rate=rate)
            if not idx:
                return fit
            model[idx[0]] = build_candidate("time_offset", ref.ctx, modelled_rate=rate)
            fit = fit_model(ref, _stack(model, n), fit_rows)
        return fit

    declared_fit = refresh_output_stage(declared_fit)
    found: list[Finding] = []
    rounds: list[list[dict]] = []
    not_distinguished: list[dict] = []
    current = declared_fit
    for rnd in range(max_rounds):
        base = _stack(model, n)
        scores = {}
        for kind, c in pool.items():
            say(f"round {rnd + 1}: testing {kind}")
            scores[kind] = held_out_score(ref, base, c.regressors, current, _bounds(model + [c]))
        rejected = {k: why for k, s in scores.items() if (why := pool[k].check(s.theta_new)) and s.gain > 0}
        table = [{"effect": k, "gain": (s.gain if math.isfinite(s.gain) else None), "added_parameters": s.added_rank,
                  "held_out_rms_before": s.rms_before, "held_out_rms_after": s.rms_after, "n_eff": s.n_eff,
                  **({"rejected": rejected[k]} if k in rejected else {})}
                 for k, s in sorted(scores.items(), key=lambda kv: -kv[1].gain)]
        scores = {k: s for k, s in scores.items() if k not in rejected}
        rounds.append(table)
        for k, s in scores.items():
            if s.added_rank == 0 and k not in not_tested:
                not_tested[k] = ("no excitation on this recording: its regressor is zero or already spanned by the "
                                 "model (cannot be distinguished from what is in it)")
        live = {k: s for k, s in scores.items() if s.added_rank > 0}
        if any(s.gain > 0 for k, s in live.items() if k not in CATCH_ALL):
            # a slow bias that a measured channel explains (temperature, field, ...) is that channel's
            # effect; the time spline of bias drift is the model of what nothing measured explains
            live = {k: s for k, s in live.items() if k not in CATCH_ALL}
        if not live:
            break
        best_kind, best = max(live.items(), key=lambda kv: kv[1].gain)
        if best.gain <= 0:
            break
        margin = best.added_rank * math.log(best.n_eff)
        rivals = [k for k, s in live.items() if k != best_kind and s.gain > 0 and best.gain - s.gain < margin]
        if rivals:
            not_distinguished.append({"round": rnd + 1, "chosen": best_kind, "rivals": rivals,
                                      "why": f"their held-out gains are within the chosen one's penalty ({margin:.1f}) "
                                             "of it: on this recording they explain the same residual"})
        cand = pool.pop(best_kind)
        model.append(cand)
        current = refresh_output_stage(fit_model(ref, _stack(model, n), fit_rows,
                                                 theta0=np.concatenate([current.theta, np.zeros(cand.n_params)]),
                                                 bounds=_bounds(model)))
        found.append(Finding(best_kind, {}, {}, {
            "round": rnd + 1, "criterion_gain": best.gain, "added_parameters": best.added_rank,
            "n_eff": best.n_eff, "held_out_rms_before": best.rms_before, "held_out_rms_after": best.rms_after,
            "explained_fraction": 1 - (best.rms_after / best.rms_before) ** 2, "follows": cand.follows,
            "rivals": rivals}, ""))

    # final parameters on all rows; errors on held-out rows
    full = fit_model(ref, _stack(model, n), theta0=current.theta, bounds=_bounds(model))
    params = _params(model, full)
    declared_params = {k: v for p in params[: len(declared)] for k, v in p.items()}
    weak = [f"{k} ± {v['sigma'] * 100:.2g} %" for k, v in declared_params.items()
            if k.split(".")[0] in _DIMENSIONLESS and v["sigma"] > 1e-3]
    if weak:
        notes.append("weakly determined (σ > 0.1 %: little motion excites them): " + ", ".join(weak))
    unit = "°/s" if ref.row_unit == "rad/s" else "weighted"
    scale = DEG if ref.row_unit == "rad/s" else 1.0
    r_before, r_after = declared_fit.residual, current.residual
    err_b = {"held_out_residual_rms": _rms(r_before[held]) * scale, "unit": unit}
    err_a = {"held_out_residual_rms": _rms(r_after[held]) * scale, "unit": unit}
    if isinstance(ref, GravityReference):
        err_b.update(ref.split_rms(r_before, held))
        err_a.update(ref.split_rms(r_after, held))
    y = np.asarray(rec.gyro_rad_s)
    att_b = _attitude_rms(ref, rec, y - _stack(model[: len(declared)], n) @ declared_fit.theta)
    if att_b is not None:
        err_b["strapdown_orientation_rms_deg"] = att_b
        y_now = getattr(ref, "y_rad_s", None)
        y_now = y if y_now is None else y_now   # the time offset found is undone on the gyro
        err_a["strapdown_orientation_rms_deg"] = _attitude_rms(ref, rec, y_now - _stack(model, n) @ current.theta)
        err_b["strapdown_orientation_rms_deg_raw_gyro"] = _attitude_rms(ref, rec, y)

    final_found = []
    for f, c, p in zip(found, model[len(declared):], params[len(declared):]):
        vals = np.array([v["value"] for v in p.values()])
        sigs = np.array([v["sigma"] for v in p.values()])
        effect = c.to_effect(vals)
        extra = {}
        if f.effect == "random_walk":
            k, sk = _drift_k(ref, model)
            effect = RandomWalk(value=np.full(3, k) if math.isfinite(k) else np.zeros(3))
            extra = {"random_walk.value": {"value": k, "sigma": sk}}
            p = {**extra}  # the knot biases are a realisation, not parameters of the device
            text = (f"bias drift with random-walk coefficient K = {k * DEG * 3600 * 60:.3g} ± {sk * DEG * 3600 * 60:.2g} "
                    "°/h/√h (restricted ML on the residual)") if math.isfinite(k) else _summary(f.effect, vals, sigs)
        elif f.effect == "time_offset":
            vals = vals + delay["total_s"]
            p = {"time_offset.delay_s": {"value": float(vals[0]), "sigma": float(sigs[0])}}
            effect = TimeOffset(delay_s=float(vals[0]))
            text = _summary(f.effect, vals, sigs)
        else:
            text = _summary(f.effect, vals, sigs)
        ev = f.evidence
        trace = (f"the residual follows {ev['follows']} → {text}; adding it cut the held-out residual from "
                 f"{ev['held_out_rms_before'] * scale:.4g} to {ev['held_out_rms_after'] * scale:.4g} {unit} "
                 f"(G = {ev['criterion_gain']:.0f} for {ev['added_parameters']} parameter(s))")
        if ref.kind == "optical" and f.effect == "time_offset":
            trace += (" — against an optical reference this is the IMU's own delay plus the synchronisation of the two "
                      "systems; one recording cannot separate them")
        if ref.kind == "optical" and f.effect == "misalignment":
            trace += (" — a rotation between the IMU and the optical body frame (the reference's alignment) looks exactly "
                      "like this")
        final_found.append(Finding(f.effect, p, _jsonable(effect.to_dict()), {**ev, "summary": text}, trace))

    unexplained = _unexplained(ref, rec, r_after, held)
    checks = {"quantization_lsb": _quantization(y), "saturated_samples": int(check.saturated.sum()),
              "warnings": list(check.warnings)}
    follows = {c.effect: c.follows_series for c in model[len(declared):]}
    return CloseloopResult(
        ref.kind, ref.description, notes, declared, declared_params, final_found, unexplained, not_tested,
        not_distinguished, err_b, err_a, checks, rounds, ref.row_time_s, ref.row_axis, held, r_before, r_after, follows,
        ref.rows_of if isinstance(ref, RateReference) else None)


def _no_reference(rec: Recording, declared: list[str], why: str, check) -> CloseloopResult:
    """The report of a recording that cannot separate candidates: say why, guess nothing."""
    kinds = [k for k in candidate_kinds() if k not in declared]
    return CloseloopResult(
        "none", "no usable reference", [why] + list(check.warnings), declared, {}, [],
        {"spectral_lines": [], "channel_correlations": [], "whiteness": {}, "summary": "not analysed: no reference"},
        {k: f"not distinguishable on this recording: {why}" for k in kinds}, [], {}, {},
        {"quantization_lsb": _quantization(np.asarray(rec.gyro_rad_s)), "saturated_samples": int(check.saturated.sum()),
         "warnings": list(check.warnings)}, [])


def _error_stage_rate(ref: Reference, model: list[Candidate], theta: np.ndarray) -> np.ndarray:
    """ω_ref + Σ (error-stage effects) R θ: the rate the sensor's output stage receives (rad/s, body)."""
    out = np.array(ref.ctx.omega_true_rad_s, dtype=float, copy=True)
    i = 0
    for c in model:
        if EFFECTS[c.effect].stage == "error":
            out += c.regressors @ theta[i : i + c.n_params]
        i += c.n_params
    return out


def _drift_k(ref: Reference, model: list[Candidate]) -> tuple[float, float]:
    """K of the bias drift: REML on the block means of the residual of the model without the drift."""
    if not isinstance(ref, RateReference):
        return float("nan"), float("nan")
    others = [c for c in model if c.effect != "random_walk"]
    fit = fit_model(ref, _stack(others, ref.ctx.t_s.size))
    r = fit.residual.reshape(-1, 3)
    t = ref.row_time_s.reshape(-1, 3)[:, 0]
    block_s = max(1.0, (t[-1] - t[0]) / 400.0)  # ≤ 400 blocks: the REML is O(n³) in them
    b = time_block_index(t, block_s)
    nb = int(b.max())  # drop the last partial block
    keep = b < nb
    means, _ = block_means(b[keep], r[keep], nb)
    return random_walk_mle(list(means.T), block_s)


def _jsonable(d: dict) -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            out[k] = str(v)
        elif isinstance(v, tuple):
            out[k] = list(v)
        else:
            out[k] = v
    return out


def _unexplained(ref: Reference, rec: Recording, r: np.ndarray, held: np.ndarray) -> dict:
    if not isinstance(ref, RateReference):
        groups = ref.groups
        worst = int(groups[np.argmax(np.abs(r))])
        return {"spectral_lines": [], "channel_correlations": [], "whiteness": {},
                "summary": f"self-consistency rows are per pose, not a time series: no spectral or channel tests; "
                           f"largest weighted residual {np.max(np.abs(r)):.2f} at pose {worst}"}
    blocks = r.reshape(-1, 3)
    fs = 1.0 / (float(np.median(np.diff(rec.t_s))) * ref.block)
    lines = spectral_lines(blocks, fs)
    corr = channel_correlations(blocks, _channels(ref, rec))
    white = whiteness(blocks)
    parts = []
    if lines:
        l0 = lines[0]
        parts.append(f"spectral line at {l0.frequency_hz:.2f} Hz on {l0.axis} (amplitude {l0.amplitude_rad_s * DEG:.3g} °/s, "
                     f"{l0.ratio:.0f}× the background)" + (f" and {len(lines) - 1} more" if len(lines) > 1 else ""))
    if corr:
        c0 = corr[0]
        parts.append(f"residual {c0.axis} correlates with {c0.channel} (ρ = {c0.rho:.3f}, {c0.z:.1f}σ)"
                     + (f" and {len(corr) - 1} more channel pairs" if len(corr) > 1 else ""))
    dw = ref.rows_of(np.gradient(ref.ctx.omega_true_rad_s, ref.ctx.t_s, axis=0)).reshape(-1, 3)
    jitter = variance_growth(blocks, dw)
    if jitter:
        parts.append(f"residual variance grows with (dω/dt)² as sampling-time jitter of {jitter['jitter_s'] * 1e3:.2f} ms "
                     f"would ({jitter['z']:.1f}σ)")
    taus = [white[f"tau_int_{a}"] for a in "xyz"]
    parts.append(f"residual autocorrelation time {min(taus):.1f}–{max(taus):.1f} samples (1 = white)")
    return {"spectral_lines": [asdict(l) for l in lines], "channel_correlations": [asdict(c) for c in corr],
            "whiteness": white, "variance_growth": jitter, "summary": "; ".join(parts)}
