"""Gyrocompassing: true heading from the horizontal component of the Earth's rotation, the gyro bias cancelled by
turning the board between positions ("Application of Gyro-Theodolite Orientation in Mine Surveying"; Titterton & Weston,
*Strapdown Inertial Navigation Technology*, 2nd ed., §10.3 "gyrocompassing").

**Model.** The board is held still in P positions k, turned between them by α_k about one body
axis a (a table or tripod head; α from the table's encoder or from the gyro).  A vector fixed in
the world appears turned by −α_k in the body frame, R_k = R(a, −α_k), so the mean gyro output of
hold k (body RFU, rad/s) is

    m_k = c + R_k w + e_k,        c = b + Ω_E (ω̂_ie·a) a   (bias + the Earth rate along a),
                                  w = the Earth rate ⊥ a at position 1 (≈ Ω_E cos L · North),

whatever the bias b: everything fixed in the body frame goes into c, everything fixed in the
world turns with R_k.  Projected on the plane ⊥ a (basis e₁, e₂ = a × e₁) that is linear in
(c_h, w): 2P equations, 4 unknowns, solved by generalised least squares with the covariance Σ of
the hold means' errors e_k (:mod:`calib.noise.window_means`: white, flicker and random-walk terms of each
gyro axis, fitted on the holds' Allan deviation or given).  The accelerometer gives the same
structure, f_k = c_f + R_k g u_⊥: its turning part u_⊥ is the tilt of the table axis from the
vertical — bias-free, since the accelerometer bias is fixed in the body frame — so the true up
at position 1 is U = u_⊥ + √(1 − |u_⊥|²) â.  With the latitude L known, the Earth rate at
position 1 is ω = w + s â with s fixed by ω·U = Ω_E sin L, North = the part of ω ⊥ U, and

    ψ = atan2(F·E, F·N),   E = N × U,   F = (0, 1, 0) (forward axis),

the heading of the forward axis, clockwise from true North (ψ_k = ψ₁ − α_k in position k: a
turn by +α about the up axis is counter-clockwise seen from above).

**The physical limit.** Only the part of w's error perpendicular to North turns the heading:

    σ_ψ = σ_res / (Ω_E cos L),      σ_res² = tᵀ Cov(ŵ) t,   t ⊥ North in the plane,

where Cov(ŵ) = (AᵀΣ⁻¹A)⁻¹ restricted to w is the **bias residual**: what the multi-position
differencing leaves of the gyro's noise.  For white noise N and total rest time T (any number of
equally spaced positions) σ_res = N/√T; for two adjacent holds of τ each it is σ_A(τ)/√2 (the
Allan deviation at the hold time: the bias change between the holds); flicker and random walk
enter through Σ.  Reported σ = this limit for the record's procedure and noise; the Monte Carlo
(calib.scoring.instruments_mc) checks the achieved error against the limit from the true noise.

**Refusals and checks** (status ``refused`` or ``inconsistent``, never a silent answer): fewer
than two still positions; holds with motion (listed and left out); positions that are not one
turn about one axis (the accelerometer's residual); a horizontal rate that is not the Earth's
(wrong latitude, gyro scale error, a world-fixed disturbance such as the Faraday effect of an
unshielded FOG coil); a residual χ² beyond its 1e-4 quantile; a limit worse than the requested
accuracy or than 1/3 rad (the gyro cannot see the Earth turn) — with the rest time that would
reach the accuracy (:mod:`calib.instruments.northfind_plan`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gyrosim.effects import EARTH_RATE_RAD_S
from gyrosim.errors import RecordingError
from gyrosim.lazy import lazy_module
from gyrosim.recording import Recording
from gyrosim.units import RAD_S_TO_DEG_H as DEG_H

from calib.instruments.holds import fit_hold_noise, still_holds
from calib.instruments.northfind_design import Design, turning_design
from calib.noise.allan import NoiseTerms

# imported on first use (gyrosim.lazy), so that start-up and a refused file do not pay for it
stats = lazy_module("scipy.stats")

__all__ = ["NorthFinding", "HoldInfo", "find_north", "Design"]

P_CHECK = 1e-4           # false-alarm probability of each consistency check
MAX_SIGMA_RAD = 1.0 / 3  # beyond ~19° the linearised heading σ means nothing: the gyro cannot see North


@dataclass(frozen=True)
class HoldInfo:
    """One hold: sample range [start, stop), index angle (°, about the turning axis, from the
    encoder or the gyro), and why it was left out (None: used)."""

    start: int
    stop: int
    index_angle_deg: float
    excluded: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "start": self.start,
            "stop": self.stop,
            "index_angle_deg": self.index_angle_deg,
            "excluded": self.excluded,
        }


@dataclass(frozen=True)
class NorthFinding:
    """Result of :func:`find_north`.  Angles in degrees, rates in °/h (names say so).

    ``status``: ``ok``; ``refused`` (cannot north-find with this record: ``reason`` says why and
    ``rest_time_needed_s`` what would do); ``inconsistent`` (an estimate exists but fails a
    check: do not use it)."""

    status: str
    reason: str
    latitude_deg: float
    heading_deg: float | None = None
    heading_sigma_deg: float | None = None
    headings_deg: tuple[float, ...] = ()
    bias_residual_sigma_deg_h: float | None = None
    horizontal_rate_deg_h: float | None = None
    horizontal_rate_expected_deg_h: float | None = None
    horizontal_rate_sigma_deg_h: float | None = None
    chi2: float | None = None
    dof: int = 0
    table_tilt_deg: float | None = None
    holds: tuple[HoldInfo, ...] = ()
    index_source: str = ""
    noise_source: str = ""
    noise: dict[str, list[float]] = field(default_factory=dict)
    accuracy_deg: float | None = None
    max_latitude_deg: float | None = None
    rest_time_needed_s: float | None = None
    rest_time_note: str = ""
    warnings: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["holds"] = [h.to_dict() for h in self.holds]
        d["headings_deg"] = list(self.headings_deg)
        d["warnings"] = list(self.warnings)
        return d


# ---------------------------------------------------------------- holds
def _meta_holds(rec: Recording) -> list[tuple[int, int, float | None]] | None:
    nf = rec.meta.get("northfind")
    if not isinstance(nf, dict) or not nf.get("holds"):
        return None
    return [(int(h["start"]), int(h["stop"]), h.get("table_angle_deg")) for h in nf["holds"]]


def _find_ranges(rec: Recording, min_hold_s: float) -> tuple[list[tuple[int, int]], list[float | None], str]:
    meta = _meta_holds(rec)
    if meta is not None:
        return [(a, b) for a, b, _ in meta], [e for _, _, e in meta], "encoder"
    from calib.session.rest import detect_rest

    rest = detect_rest(rec, window_s=1.0, min_segment_s=min_hold_s)
    return list(rest.index_ranges), [None] * len(rest.index_ranges), "gyro"


# ---------------------------------------------------------------- geometry
def _plane_basis(axis: np.ndarray) -> np.ndarray:
    """e₁ = body x (or y) projected ⊥ axis, e₂ = axis × e₁."""
    ref = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = ref - (ref @ axis) * axis
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(axis, e1)])


def _fit_turning(y: np.ndarray, alpha: np.ndarray, basis: np.ndarray, sigma: np.ndarray | None = None):
    """Least squares of y_k (P, 3) projected on the plane: θ = (c₁, c₂, w₁, w₂), the residual r,
    and — given the covariance Σ of the projected means — Cov θ = A⁺ Σ A⁺ᵀ and the residual's
    χ² = rᵀ [(I − H) Σ (I − H)ᵀ]⁺ r (H = A A⁺).

    Ordinary, not generalised, least squares: for equally spaced positions it is as efficient as
    GLS with the true Σ (to 1e-5 for fog_tactical's two- and four-position procedures), and it
    does not depend on the noise fit, whose errors cost 25 % of efficiency when used as weights."""
    yp = (y @ basis.T).reshape(-1)
    a = turning_design(alpha)
    pinv = np.linalg.pinv(a)
    theta = pinv @ yp
    res = yp - a @ theta
    if sigma is None:
        return theta, res, None, None
    resid_op = np.eye(a.shape[0]) - a @ pinv
    chi2 = float(res @ np.linalg.pinv(resid_op @ sigma @ resid_op.T, rcond=1e-10) @ res) if a.shape[0] > 4 else 0.0
    return theta, res, pinv @ sigma @ pinv.T, chi2


def _heading(w2: np.ndarray, basis: np.ndarray, axis: np.ndarray, up: np.ndarray, lat: float) -> float:
    """ψ (rad) of the forward axis at position 1 from the turning Earth-rate part w (plane coords)."""
    w3 = w2 @ basis
    s = (EARTH_RATE_RAD_S * math.sin(lat) - w3 @ up) / (axis @ up)
    omega = w3 + s * axis
    north = omega - (omega @ up) * up
    north /= np.linalg.norm(north)
    east = np.cross(north, up)
    fwd = np.array([0.0, 1.0, 0.0])
    return math.atan2(fwd @ east, fwd @ north)


# ---------------------------------------------------------------- main
def _site_latitude(rec: Recording, latitude_deg: float | None, accuracy_deg: float | None) -> float:
    """The site's latitude (°): given, or ``meta['northfind']['latitude_deg']``; refused outside ±90°."""
    if latitude_deg is None:
        nf = rec.meta.get("northfind")
        if not isinstance(nf, dict) or "latitude_deg" not in nf:
            raise RecordingError("north-finding needs the site's latitude: pass --latitude-deg (latitude_deg=...)")
        latitude_deg = float(nf["latitude_deg"])
    if not abs(latitude_deg) < 90.0:
        raise RecordingError(f"latitude {latitude_deg}° must be strictly inside ±90° (at a pole there is no North)")
    if accuracy_deg is not None and not accuracy_deg > 0:
        raise RecordingError("accuracy_deg must be > 0")
    return latitude_deg


def _levelled_axis(f: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(turning axis, plane basis, up, table tilt °) from the holds' accelerometer means ``f`` (P, 3) turned by
    ``alpha``: the axis starts at the cone centre of the means (a bias only tilts it, to second order) and is refined
    twice by the constant part of the accelerometer's turning fit."""
    axis = f.mean(axis=0) / np.linalg.norm(f.mean(axis=0))
    for _ in range(2):
        basis = _plane_basis(axis)
        th, *_ = _fit_turning(f, alpha, basis)
        c = th[:2] @ basis + (f @ axis).mean() * axis
        axis = c / np.linalg.norm(c)
    basis = _plane_basis(axis)
    th_f, *_ = _fit_turning(f, alpha, basis)
    g_mag = float(np.linalg.norm(f.mean(axis=0)))
    u_perp = th_f[2:] @ basis / g_mag
    up = u_perp + math.sqrt(max(0.0, 1 - u_perp @ u_perp)) * axis
    tilt_deg = float(np.degrees(np.arcsin(min(1.0, float(np.linalg.norm(u_perp))))))
    return axis, basis, up, tilt_deg


def _heading_jacobian(w: np.ndarray, basis: np.ndarray, axis: np.ndarray, up: np.ndarray, lat: float,
                      omega_h: float) -> tuple[np.ndarray, np.ndarray]:
    """(North's unit vector in the plane, ∂ψ/∂w): the derivative is taken at the Earth rate the latitude predicts,
    in ŵ's direction, so σ_ψ = σ_res/(Ω_E cos L) even when noise dominates |ŵ| (linearising at ŵ would shrink σ_ψ by
    Ω_E cos L/|ŵ|)."""
    north_unit = w / np.linalg.norm(w)
    w0 = north_unit * omega_h
    h = 1e-4 * omega_h
    jac = np.array([(_heading(w0 + h * e, basis, axis, up, lat) - _heading(w0 - h * e, basis, axis, up, lat)) / (2 * h)
                    for e in np.eye(2)])
    return north_unit, jac


def _verdict(result: dict, *, sig_psi: float, sig_res: float, sig_rad: float, w_mag: float, omega_h: float,
             chi2: float, chi2_f: float, dof: int, latitude_deg: float, accuracy_deg: float | None,
             noise_terms: tuple[NoiseTerms, ...], rate_hz: float, positions: int) -> tuple[str, str]:
    """(status, reason) of a north-finding: refused beyond the accuracy asked (or beyond any use), refused when the
    accelerometer says the positions are not one turn about one axis, inconsistent when the rate that turns with the
    board is not the Earth's or the hold means do not fit the model.  Adds the rest time needed to ``result``."""
    from calib.instruments.northfind_plan import rest_time_needed

    need_acc = accuracy_deg if accuracy_deg is not None else math.degrees(MAX_SIGMA_RAD)
    if sig_psi > MAX_SIGMA_RAD or sig_psi > math.radians(need_acc):
        need, note = rest_time_needed(noise_terms, latitude_deg, need_acc, rate_hz, positions=positions)
        where = (f"; to {need_acc:g}° this gyro reaches only up to latitude {result.get('max_latitude_deg'):.1f}°"
                 if result.get("max_latitude_deg") is not None else "")
        reason = (
            f"the limit of this record is σ_ψ = {math.degrees(sig_psi):.3g}° at latitude {latitude_deg:g}° "
            f"(bias residual {sig_res * DEG_H:.3g} °/h against a horizontal Earth rate of {omega_h * DEG_H:.3g} °/h)"
            + (f", worse than the requested {accuracy_deg:g}°" if accuracy_deg is not None
               else ": the gyro cannot see the Earth's rotation here")
            + where
        )
        result.update(rest_time_needed_s=need, rest_time_note=note)
        return "refused", reason
    if dof > 0 and stats.chi2.sf(chi2_f, dof) < P_CHECK:
        return "refused", (
            f"the accelerometer says the positions are not one turn about one axis (χ² = {chi2_f:.3g} on {dof} dof): "
            "the board moved between or during the holds; hold it on a fixture that only turns")
    if abs(w_mag - omega_h) > stats.norm.isf(P_CHECK / 2) * sig_rad:
        return "inconsistent", (
            f"the horizontal rate that turns with the board is {w_mag * DEG_H:.4g} ± {sig_rad * DEG_H:.2g} °/h but "
            f"the Earth's at {latitude_deg:g}° is {omega_h * DEG_H:.4g} °/h: wrong latitude, a gyro scale error, "
            "motion, or a world-fixed disturbance (e.g. the magnetic sensitivity of an unshielded FOG coil); the "
            "heading is not trusted")
    if dof > 0 and stats.chi2.sf(chi2, dof) < P_CHECK:
        return "inconsistent", (
            f"the hold means do not fit one bias plus the turning Earth rate (χ² = {chi2:.3g} on {dof} dof, p < "
            f"{P_CHECK:g}): the noise model or the index angles are wrong, or the bias jumped")
    return "ok", "north found"


def find_north(rec: Recording, latitude_deg: float | None = None, *, accuracy_deg: float | None = None,
               noise: tuple[NoiseTerms, ...] | None = None, min_hold_s: float = 10.0,
               index: str = "auto") -> tuple[NorthFinding, Design | None]:
    """North-finding on a static multi-position record (module docstring).  Returns the result
    and its :class:`Design` (None when refused before a design exists).

    Args:
        latitude_deg: the site's latitude; default ``meta['northfind']['latitude_deg']``.
        accuracy_deg: refuse when the limit σ_ψ of this record exceeds it (with the rest time needed).
        noise: per-axis gyro :class:`NoiseTerms` known beforehand (e.g. ``calib allan`` of a long
            static record); default: fitted on the holds.
        index: ``encoder`` (the table's angles in the metadata), ``gyro`` (integrated), or ``auto``.
    """
    from calib.instruments.northfind_plan import rest_time_needed

    latitude_deg = _site_latitude(rec, latitude_deg, accuracy_deg)
    lat = math.radians(latitude_deg)
    omega_h = EARTH_RATE_RAD_S * math.cos(lat)
    ranges, encoder, source = _find_ranges(rec, min_hold_s)
    if index == "gyro" or (index == "auto" and any(e is None for e in encoder)):
        source = "gyro"
    elif index == "encoder" and any(e is None for e in encoder):
        raise RecordingError("index='encoder' but the record has no table angles (meta['northfind']['holds'])")
    base = {"latitude_deg": latitude_deg, "accuracy_deg": accuracy_deg, "index_source": source}
    motion = still_holds(rec, ranges, channels="gyro+acc")
    short = [(b - a) / rec.rate_hz < min_hold_s for a, b in ranges]
    reasons = [m or (f"shorter than {min_hold_s:g} s" if s else None) for m, s in zip(motion, short)]
    used = [i for i, r in enumerate(reasons) if r is None]
    noise_source = "given" if noise is not None else "fitted on the holds"

    def refuse(reason: str, holds: tuple[HoldInfo, ...], noise_terms=None) -> tuple[NorthFinding, None]:
        need, note = None, ""
        if accuracy_deg is not None and noise_terms is not None:
            need, note = rest_time_needed(noise_terms, latitude_deg, accuracy_deg, rec.rate_hz)
        elif accuracy_deg is not None:
            note = "no still hold to measure the gyro noise on: pass noise terms (--noise) to get the rest time needed"
        return NorthFinding("refused", reason, holds=holds, rest_time_needed_s=need, rest_time_note=note,
                            noise_source=noise_source if noise_terms is not None else "", **base), None

    holds0 = tuple(HoldInfo(a, b, float("nan"), r) for (a, b), r in zip(ranges, reasons))
    try:
        noise_terms = noise if noise is not None else (fit_hold_noise(rec, [ranges[i] for i in used]) if used else None)
    except RecordingError:
        noise_terms = None
    if len(used) < 2:
        return refuse(f"{len(used)} still hold(s) of ≥ {min_hold_s:g} s: north-finding needs the board still in at "
                      "least two positions turned about the vertical (two-position 0°/180° or four-position), so that "
                      "the gyro bias cancels; this record is moving or too short", holds0, noise_terms)
    m = np.array([rec.gyro_rad_s[a:b].mean(axis=0) for a, b in (ranges[i] for i in used)])
    f = np.array([rec.acc_m_s2[a:b].mean(axis=0) for a, b in (ranges[i] for i in used)])
    axis0 = f.mean(axis=0) / np.linalg.norm(f.mean(axis=0))
    if source == "encoder":
        alpha_all = np.radians(np.array([float(e) for e in encoder]))
    else:
        alpha_all = _gyro_index_angles(rec, ranges, used, m, axis0)
    alpha = alpha_all[used] - alpha_all[used[0]]
    holds = tuple(HoldInfo(a, b, float(np.degrees(alpha_all[i] - alpha_all[used[0]])), r)
                  for i, ((a, b), r) in enumerate(zip(ranges, reasons)))
    spread = np.max(np.abs(np.angle(np.exp(1j * (alpha[:, None] - alpha[None, :])))))
    if spread < math.radians(30.0):
        return refuse(f"the still holds are at most {math.degrees(spread):.1f}° apart about the vertical: the bias "
                      "cannot be told from the Earth rate; turn the board by 90–180° between holds", holds, noise_terms)
    axis, basis, up, tilt_deg = _levelled_axis(f, alpha)
    windows = np.array([ranges[i] for i in used])
    design = Design(windows, turning_design(alpha), basis, np.zeros(2), np.zeros(2), rec.rate_hz, rec.n)
    if noise_terms is None:
        return refuse("the holds are too short to measure the gyro noise on", holds)
    th, res, cov_th, chi2 = _fit_turning(m, alpha, basis, design.sigma_matrix(noise_terms))
    w, cov_w = th[2:], cov_th[2:, 2:]
    psi = _heading(w, basis, axis, up, lat)
    north_unit, jac = _heading_jacobian(w, basis, axis, up, lat, omega_h)
    design = Design(windows, design.design, basis, jac, north_unit, rec.rate_hz, rec.n)
    sig_psi = float(math.sqrt(jac @ cov_w @ jac))
    t_perp = np.array([-north_unit[1], north_unit[0]])
    sig_res = float(math.sqrt(t_perp @ cov_w @ t_perp))
    sig_rad = float(math.sqrt(north_unit @ cov_w @ north_unit))
    w_mag = float(np.linalg.norm(w))
    dof = 2 * len(used) - 4
    excluded = [f"hold {i} ({rec.t_s[a]:.0f}–{rec.t_s[b - 1]:.0f} s): {r}"
                for i, ((a, b), r) in enumerate(zip(ranges, reasons)) if r]
    warnings = ["left out: " + "; ".join(excluded)] if excluded else []
    # accelerometer: are the positions one turn about one axis? (its noise from the holds)
    acc_noise = fit_hold_noise(rec, [ranges[i] for i in used], "acc")
    *_, chi2_f = _fit_turning(f, alpha, basis, design.sigma_matrix(acc_noise))
    result = dict(
        base,
        heading_deg=float(math.degrees(psi) % 360.0),
        heading_sigma_deg=math.degrees(sig_psi),
        headings_deg=tuple(float((math.degrees(psi - a)) % 360.0) for a in alpha),  # turning by +α about up: ψ − α
        bias_residual_sigma_deg_h=sig_res * DEG_H,
        horizontal_rate_deg_h=w_mag * DEG_H,
        horizontal_rate_expected_deg_h=omega_h * DEG_H,
        horizontal_rate_sigma_deg_h=sig_rad * DEG_H,
        chi2=chi2,
        dof=dof,
        table_tilt_deg=tilt_deg,
        holds=holds,
        noise_source=noise_source,
        noise={k: [getattr(n, k) for n in noise_terms] for k in ("arw", "bias_instability", "rate_random_walk")},
    )
    if accuracy_deg is not None:
        ratio = sig_res / (EARTH_RATE_RAD_S * math.radians(accuracy_deg))
        result["max_latitude_deg"] = float(math.degrees(math.acos(ratio))) if ratio < 1 else None
    status, reason = _verdict(result, sig_psi=sig_psi, sig_res=sig_res, sig_rad=sig_rad, w_mag=w_mag, omega_h=omega_h,
                              chi2=chi2, chi2_f=chi2_f, dof=dof, latitude_deg=latitude_deg, accuracy_deg=accuracy_deg,
                              noise_terms=noise_terms, rate_hz=rec.rate_hz, positions=len(used))
    return NorthFinding(status, reason, warnings=tuple(warnings), **result), design


def _gyro_index_angles(rec: Recording, ranges: list[tuple[int, int]], used: list[int], m: np.ndarray,
                       axis: np.ndarray) -> np.ndarray:
    """Angle (rad) of each hold about the axis, integrating the gyro over the moves between holds
    less the holds' constant rate along the axis (bias + Earth rate), trapezoidal."""
    level = float((m @ axis).mean())
    rate = rec.gyro_rad_s @ axis - level
    out = np.zeros(len(ranges))
    for k in range(1, len(ranges)):
        a, b = ranges[k - 1][1] - 1, ranges[k][0]
        r, t = rate[a : b + 1], rec.t_s[a : b + 1]
        out[k] = out[k - 1] + float(np.sum(0.5 * (r[1:] + r[:-1]) * np.diff(t)))
    return out
