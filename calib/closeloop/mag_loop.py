"""The loop on the magnetometer channel: name what the declared magnetometer model lacks, under the
same rules as the gyro's (issue 14), and report a local anomaly as unexplained structure.

Steps (each reusing the gyro loop's rule where it applies):

0. **reference** (:mod:`calib.closeloop.mag_reference`): attitude (vector residual) or magnitude;
   fit / held-out stretches of 4 s.
1. **disturbances first**: the model with every buildable candidate is fitted on the fit stretches
   and :func:`calib.mag.disturbance.find_disturbances` run on its residual, refitting without the
   flagged samples until the set stops changing (≤ 3 passes).  The richest model is used so that
   a missing sensor term (which turns with the board, everywhere) is not taken for a local field;
   what remains local is a field that changes with where the board is.  The flagged samples are
   left out of every fit and metric: the anomaly is never absorbed, and it is reported.
2. **gate** (:mod:`calib.closeloop.mag_identify`): every component of the candidate at its largest
   plausible size must show at 3σ against the current model.
3. **held-out gain**: G = n_eff ln(RSS₀/RSS₁) − Δp ln n_eff on the held-out stretches
   (n_eff = rows / τ_int of the richest model's held-out residual, as the gyro loop counts it); a
   positive G with a fitted size beyond the plausible one by 3σ is refused as a proxy.
4. **confounding**: the best candidate and any other with G > 0 that explains the same part
   (overlap ≥ ½, or one adds nothing beyond the other) form a group (the gyro loop's definition,
   :mod:`calib.closeloop.confounding`); rule: the member that explains all another does and more,
   else the larger gain (all magnetometer candidates read their cause through the same channel, the
   reference field).
5. **acceptance on every metric** (:mod:`calib.closeloop.mag_metrics`): the model with the pick
   must leave no held-out metric worse beyond its noise against the current and the declared
   model, else the pick is refused (with the metrics' disagreement) and the next is tried.
6. **report**: parameters (fitted on every stretch, block-sandwich σ), the trace of each finding,
   what could not be tested and why, and the unexplained structure: disturbances (time, size,
   position when known) and the residual's level against the magnetometer's own noise.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

from .confounding import ConfoundedGroup, MemberEvidence
from .fit import integrated_time
from .identify import Excitation
from .jsonview import JsonView
from .mag_fit import MagFit, fit_mag
from .mag_identify import mag_excitation
from .mag_metrics import detect_disturbances, mag_metrics
from .mag_reference import MagReference, build_mag_reference
from .mag_terms import MAG_TERMS, mag_term
from .metrics import MetricChange, compare_metrics, explain_disagreement
from .select import CandidateScore, Rejection

__all__ = ["MagFinding", "MagLoopResult", "run_mag_loop", "MAG_RULE", "reference_frame_note", "not_analysed"]

MIN_OVERLAP = 0.5
MAG_RULE = ("a member that explains all another does and more first; else the larger held-out gain (every magnetometer "
            "candidate reads its cause through the same channel: the reference field)")


@dataclass(frozen=True)
class MagFinding:
    effect: str
    params: dict[str, dict[str, float]]
    model: dict                  # the magnetometer effect as gyrosim serialises it (µT, rad)
    evidence: dict
    trace: str


@dataclass(frozen=True)
class MagLoopResult(JsonView):
    reference: str
    reference_description: str
    notes: list[str]
    declared: list[str]
    declared_params: dict[str, dict[str, float]]
    found: list[MagFinding]
    unexplained: dict
    not_tested: dict[str, str]
    not_distinguished: list[ConfoundedGroup]
    error_before: dict[str, float]
    error_after: dict[str, float]
    metrics: list[MetricChange] = field(default_factory=list)
    rejected: list[Rejection] = field(default_factory=list)
    rounds: list[list[CandidateScore]] = field(default_factory=list)   # held-out RMS in µT
    identifiability: list[Excitation] = field(default_factory=list)
    tested: list[str] = field(default_factory=list)

    @property
    def found_kinds(self) -> list[str]:
        return [f.effect for f in self.found]

    @property
    def disturbances(self) -> list[dict]:
        return list(self.unexplained.get("disturbances", []))

    def to_json(self) -> dict:
        return {"reference": self.reference, "reference_description": self.reference_description, "notes": self.notes,
                "declared": self.declared, "declared_params": self.declared_params,
                "found": [asdict(f) for f in self.found], "unexplained": self.unexplained,
                "not_tested": self.not_tested, "not_distinguished": [g.to_json() for g in self.not_distinguished],
                "error_before": self.error_before, "error_after": self.error_after,
                "metrics": [m.to_json() for m in self.metrics], "rejected": [r.to_json() for r in self.rejected],
                "rounds": [[s.to_json() for s in r] for r in self.rounds],
                "identifiability": [e.to_json() for e in self.identifiability], "tested": self.tested}


def not_analysed(why: str) -> MagLoopResult:
    """The magnetometer part of a report when the channel cannot be used (said, nothing guessed)."""
    return MagLoopResult("none", "not analysed", [f"magnetometer not analysed: {why}"], [], {}, [], {},
                         {k: f"not analysed: {why}" for k in MAG_TERMS}, [], {}, {})


# ================================================================ helpers
@dataclass(frozen=True)
class _Ctx:
    ref: MagReference
    exclude: np.ndarray
    n_eff: float
    noise_ut: float        # σ_w of the gate (calib.closeloop.mag_identify)

    @property
    def fit_rows(self) -> np.ndarray:
        return self.ref.rows(held=False, exclude=self.exclude)

    @property
    def held_rows(self) -> np.ndarray:
        return self.ref.rows(held=True, exclude=self.exclude)

    def fit(self, kinds: tuple[str, ...], start: MagFit | None = None, rows: np.ndarray | None = None) -> MagFit:
        theta0 = None
        if start is not None:
            extra = sum(mag_term(k).n_params for k in kinds[len(start.kinds):])
            theta0 = np.concatenate([start.theta, np.zeros(extra)])
        return fit_mag(self.ref, kinds, self.fit_rows if rows is None else rows, theta0)

    def gain(self, before: MagFit, after: MagFit) -> float:
        rss0, rss1 = before.rss(self.held_rows), after.rss(self.held_rows)
        dp = after.rank - before.rank
        if dp <= 0 or rss1 <= 0:
            return -math.inf
        return self.n_eff * math.log(rss0 / rss1) - dp * math.log(self.n_eff)

    def rms(self, f: MagFit) -> float:
        r = f.residual[self.held_rows]
        return float(np.sqrt(np.mean(r**2))) if r.size else math.nan

    def metrics(self, f: MagFit) -> dict:
        return mag_metrics(self.ref, f, self.exclude)


def _mask(ref: MagReference, kinds: tuple[str, ...]) -> tuple[np.ndarray, MagFit]:
    """Step 1 of the module docstring: the disturbance mask of the richest model."""
    exclude = np.zeros(ref.t_s.size, bool)
    f = fit_mag(ref, kinds, ref.rows(held=False))
    for _ in range(3):
        new, _ = detect_disturbances(ref, f)
        if np.array_equal(new, exclude):
            break
        exclude = new
        f = fit_mag(ref, kinds, ref.rows(held=False, exclude=exclude), f.theta)
    return exclude, f


def _noise(ref: MagReference, f: MagFit, exclude: np.ndarray) -> tuple[float, float]:
    """(n_eff of the held-out rows, σ_w of the gate) from the richest model's held-out residual."""
    held = ref.rows(held=True, exclude=exclude)
    r = f.residual[held]
    tau = max(float(np.mean([integrated_time(r[:, a]) for a in range(r.shape[1])])), 1.0)
    sigma = float(np.sqrt(np.mean(r**2))) * math.sqrt(tau)
    return max(r.size / tau, 2.0), max(ref.noise_ut, sigma)


def _implausible(kind: str, f: MagFit) -> str | None:
    term = mag_term(kind)
    th = f.theta[-term.n_params:]
    sig = np.sqrt(np.maximum(np.diag(f.cov), 0.0))[-term.n_params:]
    over = np.abs(th) - 3 * sig > term.plausible_max
    if not np.any(over):
        return None
    j = int(np.argmax(np.abs(th)))
    fac, unit = term.display
    return (f"fitted {kind} reaches {th[j] * fac:.3g} {unit}, beyond the largest plausible size "
            f"({term.plausible_max * fac:.3g} {unit}) by more than 3σ: a proxy for something else, not this effect")


def _confounded(c: _Ctx, cur: MagFit, fits: dict[str, MagFit], gains: dict[str, float], best: str,
                rnd: int) -> tuple[str, ConfoundedGroup | None]:
    rss0 = cur.rss(c.held_rows)
    members, wider = [], []
    for k, fk in fits.items():
        if k == best or gains[k] <= 0:
            continue
        both = c.fit(cur.kinds + (best, k), cur)
        rb, rc, rbc = fits[best].rss(c.held_rows), fk.rss(c.held_rows), both.rss(c.held_rows)
        e_b, e_c = rss0 - rb, rss0 - rc
        overlap = (e_b - (rc - rbc)) / min(e_b, e_c) if min(e_b, e_c) > 0 else 0.0
        g_cb, g_bc = c.gain(fits[best], both), c.gain(fk, both)
        if overlap >= MIN_OVERLAP or g_cb <= 0 or g_bc <= 0:
            h = c.held_rows
            d_b, d_c = (cur.residual[h] - fits[best].residual[h]).ravel(), (cur.residual[h] - fk.residual[h]).ravel()
            den = float(np.linalg.norm(d_b) * np.linalg.norm(d_c))
            members.append(MemberEvidence(k, "reference_field", gains[k], 1 - rc / rss0, float(overlap), float(g_cb),
                                          float(g_bc), float(d_b @ d_c) / den if den > 0 else math.nan,
                                          mag_term(k).separated_by))
            if g_bc <= 0 < g_cb:
                wider.append(k)
    if not members:
        return best, None
    chosen = max(wider, key=lambda k: gains[k]) if wider else best
    own = MemberEvidence(best, "reference_field", gains[best], 1 - fits[best].rss(c.held_rows) / rss0, 1.0,
                         gains[best], gains[best], 1.0, mag_term(best).separated_by)
    ev = (own,) + tuple(members)
    names = [m.effect for m in ev]
    seps = "; or ".join(dict.fromkeys(m.separated_by for m in ev))
    why = (f"{', '.join(names)} explain the same part of the held-out field residual on this recording; chosen "
           f"{chosen} by the rule: {MAG_RULE}")
    return chosen, ConfoundedGroup(rnd, chosen, ev, MAG_RULE, seps, why)


def _accept(c: _Ctx, cur: MagFit, declared: MagFit, new: MagFit, kind: str, rnd: int
            ) -> tuple[list[MetricChange], Rejection | None]:
    current = compare_metrics(c.metrics(cur), c.metrics(new))
    checks = [("the current model", current)]
    if cur is not declared:
        checks.append(("the declared model", compare_metrics(c.metrics(declared), c.metrics(new))))
    caveat = "the reference attitude's own frame and errors" if c.ref.source == "optical" else None
    for against, changes in checks:
        worse = [m for m in changes if m.verdict == "worse"]
        if worse:
            why = (f"adding {kind} makes {', '.join(m.describe() for m in worse)} worse than {against} beyond its "
                   f"noise (z > {worse[0].threshold:.2f})")
            return current, Rejection(rnd, kind, against, tuple(changes),
                                      explain_disagreement(list(changes), "the magnetometer's residual rows", caveat),
                                      why)
    return current, None


def _params(ref: MagReference, f: MagFit, kind: str) -> tuple[np.ndarray, np.ndarray]:
    i = (3 if ref.has_attitude else 1) + sum(mag_term(k).n_params for k in f.kinds[: f.kinds.index(kind)])
    n = mag_term(kind).n_params
    sig = np.sqrt(np.maximum(np.diag(f.cov), 0.0))
    return f.theta[i : i + n], sig[i : i + n]


def _jsonable_effect(e) -> dict:
    out = {}
    for k, v in e.to_dict().items():
        out[k] = v.tolist() if isinstance(v, np.ndarray) else list(v) if isinstance(v, tuple) else v
    return out


def reference_frame_note(mag: MagLoopResult, gyro_axes: np.ndarray | None) -> str | None:
    """When the magnetometer's ``frame_rotation`` was found against a reference that also fitted the
    gyro's axes: compare the magnetometer's rotation θ with the rotation part of the gyro's fitted
    axis matrix M (declared non-orthogonality plus any misalignment found, y = (I + S + M) ω; its
    antisymmetric part [a]×).  A rotation of the reference's body frame against the IMU frame acts on
    both sensors alike: m ≈ (I − [θ]×) b and y ≈ (I + [a]×) ω with a = −θ.  Agreement points to the
    reference frame, not to the magnetometer."""
    f = next((x for x in mag.found if x.effect == "frame_rotation"), None)
    if f is None or gyro_axes is None:
        return None
    theta = np.array([v["value"] for v in f.params.values()])
    m = np.asarray(gyro_axes, float)
    a = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    d = np.degrees(np.linalg.norm(theta + a))
    deg = lambda x: ", ".join(f"{y:.2f}" for y in np.degrees(x))  # noqa: E731
    same = d < 0.5 * max(np.degrees(np.linalg.norm(theta)), 1e-9)
    return (f"the magnetometer's frame_rotation ({deg(theta)})° and the rotation part of the gyro's fitted axes "
            f"against the same reference (−a = {deg(-a)})° differ by {d:.2f}°: "
            + ("the same rotation seen by both sensors — most likely the reference's body frame against the IMU "
               "frame, not the magnetometer's own misalignment" if same else
               "not the same rotation — the magnetometer's axes are rotated against the IMU's beyond what the "
               "reference frame explains"))


# ================================================================ the loop
def run_mag_loop(rec: Recording, declared: tuple[str, ...] | list[str] = (), *, holdout_s: float = 4.0,
                 candidates: list[str] | None = None, max_rounds: int = 4, reference: str | None = None
                 ) -> MagLoopResult:
    """The module docstring's loop on ``rec``'s magnetometer channel (``declared``: magnetometer
    kinds the user's model already holds; ``candidates``: restrict the pool)."""
    if rec.mag_ut is None:
        return not_analysed("the recording has no magnetometer channel")
    try:
        ref = build_mag_reference(rec, holdout_s, reference)
    except RecordingError as err:
        return not_analysed(str(err))
    declared = tuple(declared)
    not_tested: dict[str, str] = {}
    for k in declared:
        if mag_term(k).needs_attitude and not ref.has_attitude:
            raise RecordingError(f"declared magnetometer effect {k!r} needs an attitude reference, which this "
                                 "recording lacks")
    pool = [k for k in (candidates if candidates is not None else MAG_TERMS) if k not in declared]
    for k in list(pool):
        if mag_term(k).needs_attitude and not ref.has_attitude:
            not_tested[k] = mag_excitation(ref, fit_mag(ref, declared, ref.rows(held=False)), k, ref.valid,
                                           ref.noise_ut).reason
            pool.remove(k)
    exclude, rich = _mask(ref, declared + tuple(pool))
    c = _Ctx(ref, exclude, *_noise(ref, rich, exclude))
    declared_fit = c.fit(declared)
    cur = declared_fit
    rounds: list[list[CandidateScore]] = []
    excitations: list[Excitation] = []
    rejected: list[Rejection] = []
    added: list[dict] = []
    groups: list[ConfoundedGroup] = []
    for rnd in range(1, max_rounds + 1):
        if not pool:
            break
        fits, gains, table, live = {}, {}, [], {}
        for k in pool:
            exc = mag_excitation(ref, cur, k, c.fit_rows, c.noise_ut)
            excitations.append(exc)
            if not exc.identifiable:
                not_tested[k] = f"not identifiable on this recording: {exc.reason}"
                continue
            not_tested.pop(k, None)
            f = c.fit(cur.kinds + (k,), cur)
            fits[k], gains[k] = f, c.gain(cur, f)
            why = _implausible(k, f) if gains[k] > 0 else None
            table.append(CandidateScore(k, gains[k] if math.isfinite(gains[k]) else None, f.rank - cur.rank,
                                        c.rms(cur), c.rms(f), c.n_eff, why))
            if gains[k] > 0 and not why:
                live[k] = gains[k]
            elif why:
                not_tested[k] = f"refused: {why}"
        table.sort(key=lambda s: -(s.gain if s.gain is not None else -math.inf))
        rounds.append(table)
        pick = None
        while live:
            best = max(live, key=live.get)
            chosen, group = _confounded(c, cur, {k: fits[k] for k in live}, gains, best, rnd)
            changes, rej = _accept(c, cur, declared_fit, fits[chosen], chosen, rnd)
            if rej is None:
                pick = chosen
                added.append({"round": rnd, "effect": chosen, "gain": gains[chosen], "rms_before": c.rms(cur),
                              "rms_after": c.rms(fits[chosen]), "metrics": changes, "group": group,
                              "excitation": next(e for e in reversed(excitations) if e.effect == chosen)})
                if group is not None:
                    groups.append(group)
                break
            rejected.append(rej)
            not_tested[chosen] = f"refused by the acceptance on every metric: {rej.why}"
            live.pop(chosen)
            pool.remove(chosen)
        if pick is None:
            break
        pool.remove(pick)
        not_tested.pop(pick, None)
        cur = fits[pick]
    return _report(rec, c, declared, declared_fit, cur, added, not_tested, groups, rounds, excitations, rejected)


def _report(rec, c: _Ctx, declared, declared_fit: MagFit, cur: MagFit, added, not_tested, groups, rounds,
            excitations, rejected) -> MagLoopResult:
    ref = c.ref
    final = c.fit(cur.kinds, cur, rows=ref.valid & ~c.exclude)        # parameters on every stretch
    declared_params = {}
    for k in declared:
        v, s = _params(ref, final, k)
        for n, a, b in zip(mag_term(k).param_names, v, s):
            declared_params[f"{k}.{n}"] = {"value": float(a), "sigma": float(b)}
    base = final.theta[: 3 if ref.has_attitude else 1]
    found = []
    for a in added:
        k = a["effect"]
        term = mag_term(k)
        v, s = _params(ref, final, k)
        summ = term.summary(v, s)
        changes = a["metrics"]
        trace = (f"the residual follows {term.driver} → {summ}; adding it cut the held-out field residual from "
                 f"{a['rms_before']:.4g} to {a['rms_after']:.4g} µT (G = {a['gain']:.0f} for {term.n_params} parameter(s))")
        others = [m for m in changes if m.name != "held_out_field_residual_rms"]
        if others:
            trace += "; " + ", ".join(m.describe() for m in others)
        if k == "frame_rotation" and ref.source == "optical":
            trace += (" — against an optical reference, a rotation between the optical body frame and the IMU frame "
                      "looks exactly like this; a misalignment the gyro loop finds against the same reference points "
                      "to the reference frame, not the magnetometer")
        g = a["group"]
        if g is not None:
            trace += f". Confounded with {', '.join(g.rivals)} (under not_distinguished); separated by: {g.separate_by}"
        params = {n: {"value": float(x), "sigma": float(y)} for n, x, y in zip(term.param_names, v, s)}
        evidence = {"round": a["round"], "criterion_gain": a["gain"], "held_out_rms_before_uT": a["rms_before"],
                    "held_out_rms_after_uT": a["rms_after"], "identifiability": a["excitation"].to_json(),
                    "metrics": [m.to_json() for m in changes], "rivals": g.rivals if g is not None else [],
                    "summary": summ}
        found.append(MagFinding(k, params, _jsonable_effect(term.to_effect(v)), evidence, trace))
    m_before, m_after = c.metrics(declared_fit), c.metrics(cur)
    metrics = compare_metrics(m_before, m_after) if added else []
    err_b = {k: v.value for k, v in m_before.items()}
    err_a = {k: v.value for k, v in m_after.items()}
    notes = list(ref.warnings)
    if ref.saturated:
        notes.append(f"{ref.saturated} saturated magnetometer samples excluded")
    dis = explain_disagreement(metrics, "the magnetometer's residual rows", None)
    tested = sorted({e.effect for e in excitations if e.identifiable})
    if not tested and not found:
        notes.insert(0, f"nothing could be tested on the magnetometer: no candidate is identifiable here "
                        f"({len(not_tested)} reasons under not_tested)")
    unexplained = _unexplained(c, final, base, not_tested)
    if dis:
        notes.append(f"after the loop: {dis}")
    return MagLoopResult(f"magnetometer/{ref.kind} ({ref.source})", ref.description, notes, list(declared),
                         declared_params, found, unexplained, not_tested, groups, err_b, err_a, metrics, rejected,
                         rounds, excitations, tested)


def _unexplained(c: _Ctx, final: MagFit, base: np.ndarray, not_tested: dict[str, str]) -> dict:
    ref = c.ref
    mask, dist = detect_disturbances(ref, final)
    parts, out = [], {}
    for d in dist:
        where = (f" near ({', '.join(f'{x:.2f}' for x in d.position_nav_m)}) m ENU"
                 if d.position_nav_m is not None else "")
        parts.append(f"local disturbance {d.t_start_s:.1f}–{d.t_end_s:.1f} s: the field magnitude leaves the fitted "
                     f"{np.linalg.norm(base):.1f} µT by up to {d.max_field_deviation_ut:.2f} µT"
                     + (f", the inclination by up to {d.max_inclination_deviation_deg:.2f}°"
                        if math.isfinite(d.max_inclination_deviation_deg) else "") + where
                     + " — a field that changes with where the board is (or when: a magnet brought near, attached, "
                       "taken off): excluded from the fit, not absorbed")
    out["disturbances"] = [d.to_dict() for d in dist]
    out["disturbed_samples"] = int(mask.sum())
    held = ref.rows(held=True, exclude=mask | c.exclude)
    r = final.residual[held]
    rms = float(np.sqrt(np.mean(r**2))) if r.size else math.nan
    ratio = rms / ref.noise_ut
    tau = float(np.mean([integrated_time(r[:, a]) for a in range(r.shape[1])])) if r.size else math.nan
    out.update(residual_rms_uT=rms, white_noise_uT=ref.noise_ut, ratio_to_noise=ratio, tau_int_samples=tau)
    if ref.noise_ut < 0.01:
        parts.append(f"residual {rms:.3g} µT with autocorrelation time {tau:.0f} samples; the field samples have no "
                     "white noise to compare with (read slower than the log and interpolated, or filtered)")
    elif ratio > 2.0:
        causes = ["the reference attitude's own error", "a time offset between reference and magnetometer"] \
            if ref.has_attitude else []
        if not_tested:
            causes.append(f"the candidates that could not be tested here ({', '.join(not_tested)})")
        causes.append("a field that varies over the room")
        parts.append(f"the residual outside disturbances is {ratio:.1f}× the magnetometer's white noise "
                     f"({ref.noise_ut:.2f} µT) with autocorrelation time {tau:.0f} samples: structure no candidate "
                     f"explains ({', '.join(causes)})")
    else:
        parts.append(f"residual {rms:.3g} µT = {ratio:.2f}× the magnetometer's white noise ({ref.noise_ut:.2f} µT), "
                     f"autocorrelation time {tau:.1f} samples")
    out["summary"] = "; ".join(parts)
    return out
