"""Static test of a tilt sensor ("Static Capacitance Test of MEMS Tilt Sensor", after
JJF 1427-2013): sensitivity, linearity, cross-axis (transverse) sensitivity, zero offset and
zero stability of each sensitive axis from holds on a dividing head (:mod:`gyrosim.tilttable`).

Per sensitive axis s (sweep s: the head turns so that s reads g sin θ), with o the other
horizontal axis and z the vertical one, the mean output of a hold is

    y_s(θ) = b_s + S_s g sin(θ + θ₀) + n_s(·) + c_so g sin θ_o + …,      S_s g sin θ₀ = c_sz g,

(b_s zero offset, S_s sensitivity, θ₀ the mechanical zero: the sensitive axis tipped out of
the board plane, so the vertical g leaks in as c_sz g; n_s the nonlinearity).

1. **Two-point method** (seed: "0° and 180° two-point method to determine the mechanical zero"):
   y_s(0°) = b_s + c_sz g, y_s(180°) = b_s − c_sz g, so b_s = ½(y₀ + y₁₈₀), c_sz = (y₀ − y₁₈₀)/2g
   and θ₀ = asin(c_sz/S_s).
2. **Sensitivity and linearity** (seed eqs. 4.4–4.5): least-squares line y_i = S a_i + b through
   the steps, a_i = g sin(θ_i + θ₀); nonlinearity = max_i |r_i| / (ŷ_max − ŷ_min) (% FS, FS the
   output span of the range), and as an angle max_i |r_i| / (S g cos θ_i).
3. **Cross-axis sensitivity** (seed eq. 4.6: the largest output per g among inputs ⊥ s): c_so
   is the slope of y_s against g sin θ in the *other* sweep, c_sz from step 1, and
   TSR_s = √(c_so² + c_sz²) / S_s (%).
4. **Zero offset** b_s (step 1) and **zero stability**: the minimum of the Allan deviation of
   axis s fitted on all still holds (IEEE 952 three-term model on paired Allan curves,
   :mod:`calib.noise.allan`; the τ range the holds cover is reported with it), and the
   seed's formula 4.7, the standard deviation of the readings over the long level hold (its σ
   from the fitted noise, :func:`calib.noise.window_means.sample_variance_moments`).

Every σ comes from the covariance of the hold means under the noise fitted on the holds
(:mod:`calib.noise.window_means`: white, flicker and random walk; the hold-to-hold drift is what limits a
static test), propagated through each least-squares fit as Cov θ = A⁺ Σ A⁺ᵀ.  Holds with motion
(:func:`calib.instruments.holds.still_holds`, on the accelerometer only) are left out and listed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.units import G0

from calib.instruments.holds import fit_hold_noise, still_holds
from calib.noise.allan import NoiseTerms, fit_allan_variance, paired_allan_deviation
from calib.noise.window_means import sample_variance_moments, window_mean_covariance

__all__ = ["TiltHold", "AxisFigures", "TiltTest", "tilt_test", "holds_from_meta", "allan_minimum", "plot_tilt"]

UG = 1e-6 * G0
MIN_STEPS = 5


@dataclass(frozen=True)
class TiltHold:
    """A hold: its sweep (sensitive axis x or y, or ``zero`` for the long level hold), kind (step,
    flip, zero), the head's angle (°), samples [start, stop), and why it was left out (None: used)."""

    sweep: str
    kind: str
    angle_deg: float
    start: int
    stop: int
    excluded: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class AxisFigures:
    """The figures of one sensitive axis with 1σ (None: not measurable, ``missing`` says why).
    Scale factor in output g per input g; offsets and stabilities in µg; angles in °."""

    axis: str
    scale_factor: float | None = None
    scale_factor_sigma: float | None = None
    nonlinearity_pct_fs: float | None = None
    nonlinearity_pct_fs_sigma: float | None = None
    nonlinearity_deg: float | None = None
    full_scale_g: float | None = None
    cross_axis_pct: float | None = None
    cross_axis_pct_sigma: float | None = None
    cross_axis_horizontal_pct: float | None = None
    cross_axis_horizontal_pct_sigma: float | None = None
    cross_axis_vertical_pct: float | None = None
    cross_axis_vertical_pct_sigma: float | None = None
    mechanical_zero_deg: float | None = None
    mechanical_zero_deg_sigma: float | None = None
    zero_offset_ug: float | None = None
    zero_offset_ug_sigma: float | None = None
    zero_stability_ug: float | None = None
    zero_stability_ug_sigma: float | None = None
    zero_stability_tau_s: float | None = None
    zero_stability_tau_range_s: tuple[float, float] | None = None
    zero_std_ug: float | None = None
    zero_std_ug_sigma: float | None = None
    zero_std_hold_s: float | None = None
    linearity_table: tuple[dict[str, float], ...] = ()
    cross_axis_table: tuple[dict[str, float], ...] = ()
    missing: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        d["linearity_table"] = list(self.linearity_table)
        d["cross_axis_table"] = list(self.cross_axis_table)
        d["missing"] = list(self.missing)
        return d


@dataclass(frozen=True)
class TiltTest:
    """Result of :func:`tilt_test`: ``status`` ``ok``, ``incomplete`` (some figures missing: see
    each axis's ``missing`` and the excluded holds) or ``refused`` (nothing measurable)."""

    status: str
    reason: str
    axes: dict[str, AxisFigures] = field(default_factory=dict)
    holds: tuple[TiltHold, ...] = ()
    noise: dict[str, float] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def excluded(self) -> list[TiltHold]:
        return [h for h in self.holds if h.excluded]

    def to_dict(self) -> dict[str, Any]:
        return {"status": self.status, "reason": self.reason, "axes": {k: v.to_dict() for k, v in self.axes.items()},
                "holds": [h.to_dict() for h in self.holds],
                "excluded_holds": [h.to_dict() for h in self.excluded], "noise": dict(self.noise),
                "warnings": list(self.warnings)}


def holds_from_meta(rec: Recording) -> list[TiltHold]:
    """The holds of a ``gyrosim tilttable`` recording (``meta['tilttable']['holds']``)."""
    tt = rec.meta.get("tilttable")
    if not isinstance(tt, dict) or not tt.get("holds"):
        raise RecordingError("the recording does not say where its holds are (meta['tilttable']['holds'], written by "
                             "gyrosim tilttable); give them as a CSV: sweep,kind,angle_deg,t_start_s,t_stop_s")
    return [TiltHold(str(h["sweep"]), str(h["kind"]), float(h["angle_deg"]), int(h["start"]), int(h["stop"]))
            for h in tt["holds"]]


def _ols(a: np.ndarray, y: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(θ, Cov θ = A⁺ΣA⁺ᵀ, residual r, Cov r = (I − H)Σ(I − H)ᵀ)."""
    pinv = np.linalg.pinv(a)
    theta = pinv @ y
    resid_op = np.eye(a.shape[0]) - a @ pinv
    return theta, pinv @ sigma @ pinv.T, resid_op @ y, resid_op @ sigma @ resid_op.T


def allan_minimum(curves: list) -> tuple[float, float, float, tuple[float, float]]:
    """(min σ_A, its σ, τ* at the minimum, the τ range searched) of the three-term model fitted on
    paired (non-overlapping, octave) Allan curves (:func:`calib.noise.allan.paired_allan_deviation`),
    over the τ the curves cover; σ by the delta method on the fit's covariance, which is honest
    for such curves (their points are nearly independent: in a Monte Carlo of tilt_001 the RMS of
    error/σ was 1.09; with overlapping curves the covariance was 1.5–5× too small)."""
    coef, cov = fit_allan_variance(curves)
    lo = min(float(c.tau_s[0]) for c in curves)
    hi = max(float(c.tau_s[-1]) for c in curves)
    tau = np.logspace(math.log10(lo), math.log10(hi), 400)
    var = coef[0] / tau + coef[1] + coef[2] * tau / 3
    k = int(np.argmin(var))
    grad = np.array([1 / tau[k], 1.0, tau[k] / 3])
    amin = math.sqrt(var[k])
    return amin, math.sqrt(max(float(grad @ cov @ grad), 0.0)) / (2 * amin), float(tau[k]), (lo, hi)


def tilt_test(rec: Recording, holds: list[TiltHold] | None = None, *, noise: tuple[NoiseTerms, ...] | None = None,
              axes: tuple[str, ...] = ("x", "y")) -> TiltTest:
    """The application note's static test of each sensitive axis (module docstring).

    ``holds``: default from the recording's metadata; ``noise``: per-axis accelerometer noise
    terms known beforehand (default: fitted on the still holds)."""
    holds = holds if holds is not None else holds_from_meta(rec)
    for h in holds:
        if not (0 <= h.start < h.stop <= rec.n):
            raise RecordingError(f"hold {h} lies outside the recording's {rec.n} samples")
    motion = still_holds(rec, [(h.start, h.stop) for h in holds], channels="acc")
    holds = [TiltHold(h.sweep, h.kind, h.angle_deg, h.start, h.stop, h.excluded or m) for h, m in zip(holds, motion)]
    used = [h for h in holds if not h.excluded]
    warnings = [f"left out: {h.sweep} {h.kind} {h.angle_deg:g}° (t = {rec.t_s[h.start]:.0f}–{rec.t_s[h.stop - 1]:.0f} "
                f"s): {h.excluded}" for h in holds if h.excluded]
    if not used:
        return TiltTest(
            "refused", "no still hold: the board moved in every hold", holds=tuple(holds), warnings=tuple(warnings)
        )
    noise = noise if noise is not None else fit_hold_noise(rec, [(h.start, h.stop) for h in used], "acc",
                                                           keep_random_walk=True)
    windows = np.array([(h.start, h.stop) for h in used])
    means = np.array([rec.acc_m_s2[h.start : h.stop].mean(axis=0) for h in used])
    cache: dict[NoiseTerms, np.ndarray] = {}
    for term in noise:  # the three axes usually share one noise model: one covariance
        if term not in cache:
            cache[term] = window_mean_covariance(term, windows, rec.rate_hz, rec.n)
    cov = [cache[term] for term in noise]
    index = {id(h): k for k, h in enumerate(used)}
    result = {s: _axis_figures(rec, s, [o for o in axes if o != s], used, index, means, cov, noise) for s in axes}
    missing = [f"{s}: {m}" for s, f in result.items() for m in f.missing]
    status = (
        "ok"
        if not missing and not warnings
        else ("refused" if all(f.scale_factor is None for f in result.values()) else "incomplete")
    )
    reason = ("all figures measured" if status == "ok" else
              "; ".join(missing + ([f"{len(warnings)} hold(s) left out for motion"] if warnings else [])))
    nz = {"white_ug_per_sqrt_hz": noise[0].arw / UG, "flicker_ug": noise[0].bias_instability / UG,
          "random_walk_ug_per_sqrt_s": noise[0].rate_random_walk / UG}
    return TiltTest(status, reason, result, tuple(holds), nz, tuple(warnings))


def _axis_figures(rec: Recording, s: str, others: list[str], used: list[TiltHold], index: dict, means: np.ndarray,
                  cov: list[np.ndarray], noise: tuple[NoiseTerms, ...]) -> AxisFigures:
    i = "xyz".index(s)
    f: dict[str, Any] = {"axis": s}
    missing: list[str] = []
    steps = sorted([h for h in used if h.sweep == s and h.kind == "step"], key=lambda h: h.angle_deg)
    flip = next((h for h in used if h.sweep == s and h.kind == "flip"), None)
    zero = next((h for h in steps if h.angle_deg == 0.0), None)
    c_ii = cov[i]
    # 1. two-point method
    c_sz = c_sz_var = None
    if flip is not None and zero is not None:
        k0, k1 = index[id(zero)], index[id(flip)]
        y0, y1 = means[k0, i], means[k1, i]
        var_d = c_ii[k0, k0] + c_ii[k1, k1] - 2 * c_ii[k0, k1]
        var_s = c_ii[k0, k0] + c_ii[k1, k1] + 2 * c_ii[k0, k1]
        c_sz, c_sz_var = (y0 - y1) / (2 * G0), var_d / (2 * G0) ** 2
        f["zero_offset_ug"], f["zero_offset_ug_sigma"] = 0.5 * (y0 + y1) / UG, 0.5 * math.sqrt(var_s) / UG
    else:
        missing.append(
            "no still 0°/180° pair: mechanical zero, zero offset and the vertical cross-axis term unmeasured"
        )
    # 2. sensitivity and linearity
    if len(steps) >= MIN_STEPS:
        ks = [index[id(h)] for h in steps]
        th = np.radians([h.angle_deg for h in steps])
        y = means[ks, i]
        sig = c_ii[np.ix_(ks, ks)]
        theta0 = 0.0
        for _ in range(2):
            a = np.stack([G0 * np.sin(th + theta0), np.ones_like(th)], axis=1)
            p, p_cov, r, r_cov = _ols(a, y, sig)
            if c_sz is not None:
                theta0 = math.asin(max(-1.0, min(1.0, c_sz / p[0])))
        span = abs(p[0]) * G0 * (np.sin(th[-1] + theta0) - np.sin(th[0] + theta0))
        j = int(np.argmax(np.abs(r)))
        f.update(
            scale_factor=float(p[0]),
            scale_factor_sigma=math.sqrt(p_cov[0, 0]),
            full_scale_g=float(span / G0),
            nonlinearity_pct_fs=float(abs(r[j]) / span * 100),
            nonlinearity_pct_fs_sigma=math.sqrt(r_cov[j, j]) / span * 100,
            nonlinearity_deg=float(np.degrees(np.max(np.abs(r) / (abs(p[0]) * G0 * np.cos(th + theta0))))),
        )
        f["linearity_table"] = tuple(
            {
                "angle_deg": float(h.angle_deg),
                "input_g": float(aa / G0),
                "output_g": float(yy / G0),
                "fit_g": float((yy - rr) / G0),
                "residual_ug": float(rr / UG),
                "residual_deg": float(np.degrees(rr / (p[0] * G0 * math.cos(t + theta0)))),
            }
            for h, aa, yy, rr, t in zip(steps, a[:, 0], y, r, th)
        )
        if c_sz is not None:
            sf = p[0]
            f["mechanical_zero_deg"] = math.degrees(theta0)
            f["mechanical_zero_deg_sigma"] = math.degrees(math.sqrt(c_sz_var) / abs(sf) / max(math.cos(theta0), 1e-9))
            f["cross_axis_vertical_pct"] = 100 * c_sz / sf
            f["cross_axis_vertical_pct_sigma"] = 100 * math.sqrt(c_sz_var) / abs(sf)
    else:
        missing.append(f"sweep {s} has {len(steps)} still step(s), fewer than {MIN_STEPS}: sensitivity and linearity "
                       "unmeasured")
    # 3. cross-axis: axis s against the other sweep's input
    rows = []
    for o in others:
        osteps = sorted([h for h in used if h.sweep == o and h.kind == "step"], key=lambda h: h.angle_deg)
        if len(osteps) < 3 or f.get("scale_factor") is None:
            missing.append(
                f"the cross-axis term of {s} needs sweep {o} with ≥ 3 still steps and the sensitivity of {s}"
            )
            continue
        ks = [index[id(h)] for h in osteps]
        th = np.radians([h.angle_deg for h in osteps])
        a = np.stack([G0 * np.sin(th), np.ones_like(th)], axis=1)
        p, p_cov, r, _ = _ols(a, means[ks, i], c_ii[np.ix_(ks, ks)])
        sf = f["scale_factor"]
        f["cross_axis_horizontal_pct"] = 100 * p[0] / sf
        f["cross_axis_horizontal_pct_sigma"] = 100 * math.sqrt(p_cov[0, 0]) / abs(sf)
        rows = [{"sweep": o, "angle_deg": float(h.angle_deg), "input_g": float(math.sin(t)), "output_g": float(yy / G0),
                 "fit_g": float((yy - rr) / G0)} for h, t, yy, rr in zip(osteps, th, means[ks, i], r)]
        if c_sz is not None:
            co, cz = p[0], c_sz
            tsr = math.hypot(co, cz)
            f["cross_axis_pct"] = 100 * tsr / sf
            f["cross_axis_pct_sigma"] = (
                100 * math.sqrt((co / tsr) ** 2 * p_cov[0, 0] + (cz / tsr) ** 2 * c_sz_var) / abs(sf) if tsr else None
            )
    f["cross_axis_table"] = tuple(rows)
    # 4. zero stability: Allan minimum over the still holds, and the readings' spread over the long level hold
    curves = [
        paired_allan_deviation(rec.acc_m_s2[h.start : h.stop, i], rec.rate_hz) for h in used if h.stop - h.start >= 20
    ]
    curves = [c for c in curves if c.tau_s.size >= 2]
    if curves:
        amin, amin_sd, tau, span = allan_minimum(curves)
        f.update(zero_stability_ug=amin / UG, zero_stability_ug_sigma=amin_sd / UG, zero_stability_tau_s=tau,
                 zero_stability_tau_range_s=span)
    else:
        missing.append("no hold long enough for an Allan deviation (≥ 20 samples)")
    level = next((h for h in used if h.kind == "zero"), None)
    if level is not None:
        sd = float(rec.acc_m_s2[level.start : level.stop, i].std(ddof=1))
        _, var_s2 = sample_variance_moments(noise[i], (level.start, level.stop), rec.rate_hz, rec.n)
        f.update(zero_std_ug=sd / UG, zero_std_ug_sigma=math.sqrt(var_s2) / (2 * sd) / UG if sd > 0 else None,
                 zero_std_hold_s=(level.stop - level.start) / rec.rate_hz)
    else:
        missing.append("no still long level hold: the zero stability by seed formula 4.7 (std of the readings) "
                       "unmeasured")
    return AxisFigures(missing=tuple(missing), **f)


def plot_tilt(res: TiltTest, path: str) -> str:
    """Output against input angle per sensitive axis (steps and fitted line, the other axis's
    cross-axis output) over the residuals from the line (µg): the application note's Figure 4.13."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes = [a for a in res.axes.values() if a.linearity_table]
    fig, ax = plt.subplots(2, max(1, len(axes)), figsize=(5.5 * max(1, len(axes)), 7), squeeze=False, sharex="col",
                           gridspec_kw={"height_ratios": [2, 1]})
    for c, a in enumerate(axes):
        t = a.linearity_table
        ang = [r["angle_deg"] for r in t]
        ax[0, c].plot(ang, [r["output_g"] for r in t], "o", label=f"axis {a.axis} output")
        ax[0, c].plot(ang, [r["fit_g"] for r in t], "-", lw=1, label=f"line: {a.scale_factor:.5f} g/g")
        for other in res.axes.values():
            if other.axis != a.axis and other.cross_axis_table:
                ct = other.cross_axis_table
                ax[0, c].plot([r["angle_deg"] for r in ct], [r["output_g"] for r in ct], "s", ms=4, alpha=0.6,
                              label=f"axis {other.axis} (cross-axis {other.cross_axis_horizontal_pct:+.2f} %)")
        ax[0, c].set_ylabel("output (g)")
        ax[0, c].set_title(f"sweep {a.axis}: nonlinearity {a.nonlinearity_pct_fs:.3f} %FS ({a.nonlinearity_deg:.4f}°)")
        ax[0, c].grid(alpha=0.3)
        ax[0, c].legend(fontsize=8)
        ax[1, c].plot(ang, [r["residual_ug"] for r in t], "o-")
        ax[1, c].axhline(0, color="k", lw=0.5)
        ax[1, c].set_xlabel("input angle (°)")
        ax[1, c].set_ylabel("residual from the line (µg)")
        ax[1, c].grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
