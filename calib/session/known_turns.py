"""Turns of a known angle as measurements of the gyro's parameters (:mod:`calib.inputs.turns` reads them).

A turn about an axis held vertical keeps gravity fixed in the body, so the filter's levelling measurement cannot say
how far the gyro turned: that axis's scale factor stays at its prior (imucal's Ferraris session: 360° turns about
each axis in turn).  The protocol knows the angle.  Each turn i over its stretch [t₀, t₁] is one scalar measurement

    z_i = A_i − u_iᵀ Σ_k ω̂_k Δt_k,   ω̂ = M_g(θ)⁻¹ (ω̃ − b_g),   M_g = I + diag(S) + N(G) (− [α×])

(u_i the body axis, A_i the stated angle; the rectangle sum of the compensated rate about the axis: a turn about a
body axis held fixed has the rate along it, so the integral is the angle — imucal's own integration), with

    ∂(u ᵀΣ ω̂ Δt)/∂θ = −u ᵀ Σ M̂⁻¹ [diag(ω̂), J_G(ω̂), I, [ω̂×]] Δt           (b, S, G, α order of θ below)

and R_i = σ_i² + N_g² T_i (the stated σ and the white noise integrated over the turn, T_i = t₁ − t₀).

The parameters are random constants, so a measurement of them may enter after the filter's last sample: the Kalman
update of the filter's final estimate and covariance with these rows is the update the filter would have made with
them (to the linearisation, which is iterated here: Gauss–Newton on the turns' rows with the filter's posterior as
the prior).  The turns' gyro noise is also in the filter's attitude propagation, but a turn about the vertical gives
the levelling rows no information about its angle, so nothing is counted twice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrosim.calibration import LINEAR_KINDS, Calibration
from gyrosim.recording import Recording
from gyrosim.rotations import skew

from calib.inputs.turns import Turns
from calib.session.model import gyro_axis_matrix, nonorthogonality_jacobians

__all__ = ["TurnRow", "turn_rows", "apply_known_turns", "known_turns_lines", "GYRO_KINDS", "TURN_OFF_SIGMA"]

# the gyro's parameter blocks a turn measures, in the Calibration's covariance order (gyro first)
GYRO_KINDS = ("bias", "scale_factor", "nonorthogonality", "gyro_acc_misalignment")
ITERATIONS = 4   # Gauss–Newton steps on the turns' rows (S moves by ~1e-2 at most: converged after 2)
TURN_OFF_SIGMA = 3.0   # a turn whose calibrated angle misses the stated one by more than this many σ is named


@dataclass(frozen=True)
class TurnRow:
    """One turn's measurement at the estimate it was evaluated at: the stated and the integrated angle (rad), its
    variance R (rad²) and H (the gyro's parameters, ``GYRO_KINDS`` order present in the calibration)."""

    label: str
    stated_rad: float
    integrated_rad: float
    r_var: float
    h: np.ndarray


def _gyro_theta(cal: Calibration) -> tuple[list[str], np.ndarray]:
    kinds = [k for k in GYRO_KINDS if cal.has("gyro", k)]
    return kinds, np.concatenate([np.asarray(cal.value("gyro", k), float) for k in kinds])


def turn_rows(gyro_rad_s: np.ndarray, t_s: np.ndarray, turns: Turns, theta: np.ndarray, kinds: list[str],
              arw_rad_s_sqrt_hz: float) -> list[TurnRow]:
    """The turns' rows (module docstring) at the gyro parameters ``theta`` (``kinds`` order, each 3 values)."""
    par = {k: theta[3 * i:3 * i + 3] for i, k in enumerate(kinds)}
    m = gyro_axis_matrix(par["scale_factor"], par["nonorthogonality"], par.get("gyro_acc_misalignment"))
    mi = np.linalg.inv(m)
    rows = []
    for turn, (i0, i1) in zip(turns.turns, turns.sample_ranges(t_s)):
        t = np.asarray(t_s[i0:i1 + 1], float)
        dt = np.diff(t)
        w = (np.asarray(gyro_rad_s[i0:i1], float) - par["bias"]) @ mi.T        # ω̂ at the left end of each step
        u = np.asarray(turn.axis, float)
        angle = float(u @ (w * dt[:, None]).sum(axis=0))
        cols = {"bias": np.tile(-mi, (w.shape[0], 1, 1)),
                "scale_factor": -mi[None] * w[:, None, :],
                "nonorthogonality": -np.einsum("ij,njk->nik", mi, nonorthogonality_jacobians(w)),
                "gyro_acc_misalignment": -np.einsum("ij,njk->nik", mi, skew(w))}
        h = np.concatenate([u @ np.einsum("nij,n->ij", cols[k], dt) for k in kinds])
        r_var = turn.sigma_rad**2 + arw_rad_s_sqrt_hz**2 * float(t[-1] - t[0])
        rows.append(TurnRow(turn.label, turn.angle_rad, angle, r_var, h))
    return rows


def apply_known_turns(cal: Calibration, rec: Recording, turns: Turns, arw_rad_s_sqrt_hz: float) -> Calibration:
    """``cal`` updated with the turns' measurements (module docstring): the gyro's bias, S, G (and α) and the
    covariance over every parameter; ``diagnostics["known_turns"]`` lists each turn's stated angle, the angle before
    and after, and its normalised innovation.  A calibration without a (finite) covariance is returned unchanged."""
    if cal.covariance is None or not len(turns) or not np.all(np.isfinite(cal.covariance)):
        return cal
    kinds, theta0 = _gyro_theta(cal)
    ng = theta0.size
    names = cal.parameter_names()[:ng]
    if [nm.split(".")[1] for nm in names[::3]] != kinds:   # the covariance's first rows are these gyro blocks
        raise ValueError(f"the calibration's parameters start {names}, not the gyro's {kinds}")
    p0 = np.asarray(cal.covariance, float)
    n = p0.shape[0]
    before = turn_rows(rec.gyro_rad_s, rec.t_s, turns, theta0, kinds, arw_rad_s_sqrt_hz)
    x = np.zeros(n)                                    # the update's change of every parameter
    for _ in range(ITERATIONS):                        # Gauss–Newton: the rows re-linearised at the new estimate
        rows = turn_rows(rec.gyro_rad_s, rec.t_s, turns, theta0 + x[:ng], kinds, arw_rad_s_sqrt_hz)
        h = np.zeros((len(rows), n))
        h[:, :ng] = np.array([r.h for r in rows])
        rv = np.diag([r.r_var for r in rows])
        y = np.array([r.stated_rad - r.integrated_rad for r in rows]) + h @ x   # z at the prior's linearisation
        s = h @ p0 @ h.T + rv
        k = p0 @ h.T @ np.linalg.inv(s)
        x = k @ y
    ikh = np.eye(n) - k @ h
    cov = ikh @ p0 @ ikh.T + k @ rv @ k.T              # Joseph form
    after = turn_rows(rec.gyro_rad_s, rec.t_s, turns, theta0 + x[:ng], kinds, arw_rad_s_sqrt_hz)
    s0 = np.array([b.h for b in before])
    s_before = s0 @ p0[:ng, :ng] @ s0.T + np.diag([b.r_var for b in before])
    report = {"source": turns.source, "turns": [
        {"label": b.label, "stated_deg": math.degrees(b.stated_rad), "integrated_before_deg": math.degrees(
            b.integrated_rad), "integrated_after_deg": math.degrees(a.integrated_rad),
         "sigma_deg": math.degrees(math.sqrt(b.r_var)),
         "normalised_innovation": float((b.stated_rad - b.integrated_rad) / math.sqrt(s_before[i, i]))}
        for i, (b, a) in enumerate(zip(before, after))]}
    new = theta0 + x[:ng]
    gyro = tuple(replace(e, value=new[3 * kinds.index(e.kind):3 * kinds.index(e.kind) + 3].copy())
                 if e.kind in kinds else e for e in cal.gyro)
    out = replace(cal, gyro=gyro, covariance=cov, diagnostics={**cal.diagnostics, "known_turns": report})
    return out if not cal.has("accelerometer", "bias") else _with_accelerometer(out, x[ng:], kinds)


def _with_accelerometer(cal: Calibration, dx: np.ndarray, kinds: list[str]) -> Calibration:
    """The accelerometer's parameters moved by their share of the update (correlated with the gyro's in P)."""
    acc_kinds = [e.kind for e in cal.accelerometer if e.kind in LINEAR_KINDS]   # the linear model's, in its order
    if dx.size != 3 * len(acc_kinds):
        return cal
    acc = tuple(replace(e, value=np.asarray(e.value, float) + dx[3 * acc_kinds.index(e.kind):
                                                                   3 * acc_kinds.index(e.kind) + 3])
                if e.kind in acc_kinds else e for e in cal.accelerometer)
    return replace(cal, accelerometer=acc)


def known_turns_lines(report: dict) -> list[str]:
    """The terminal's lines from ``diagnostics["known_turns"]``: each turn's angle after the calibration against the
    stated one; and, when one misses it by more than :data:`TURN_OFF_SIGMA` σ, a second line saying what that means —
    the turns and the session's other motion disagree on that axis's scale (on imucal's Ferraris session a gyro
    whose scale differs with the turn's direction does this, docs/real_imu.md)."""
    turns = report.get("turns") or []
    if not turns:
        return []
    lines = [f"known turns ({report.get('source', 'given')}, σ {turns[0]['sigma_deg']:.2g}°), after the calibration: "
             + ", ".join(f"{t['label']} {t['integrated_after_deg']:+.2f}° of {t['stated_deg']:+.0f}°" for t in turns)]
    off = [(t["label"], (t["integrated_after_deg"] - t["stated_deg"]) / t["sigma_deg"]) for t in turns
           if t["sigma_deg"] > 0]
    off = [(label, z) for label, z in off if abs(z) > TURN_OFF_SIGMA]
    if off:
        lines.append(", ".join(f"{label} {z:+.1f}σ off" for label, z in off) + ": the turns and the other motion "
                     "disagree on that axis's scale (a scale that differs with the turn's direction does this); "
                     "S there holds for the other motion")
    return lines
