"""imucal's Ferraris session: what drives ``kf_hand``'s gyro S_z away from imucal's, measured.

    python benchmarks/sz_ferraris.py            # ~30 s on one core; data from $GYROSIM_DATA

The setting is the one ``calib run dataset:imucal_ferraris --protocol ferraris`` uses (the six box-face poses give
the accelerometer, ``kf_hand`` with the gyro's rotation α against it, the three 360° turns as known angles).  Two
tables:

1. ``kf_hand`` variants: S ± σ, each turn's normalised innovation, the gravity carried by the calibrated gyro from
   each rest to the next (RMS angle, °, the harness's figure) and each turn's error after the calibration (°).
   Variants change the method (no turns, no α, no delay state, g-sensitivity, lever arm held at 0, accelerometer
   updates only at rests or below a rate), the timing (accelerometer shifted by whole samples) or the recording
   (only the hand-held moves 0–6; the moves 1–6 cut out at two rests of the same face), and last the gyro's z
   rate pre-compensated with a scale that depends on its sign (fitted in table 2).
2. S_z from the gravity carried across each move (the other parameters at the baseline's), and three models of
   the z scale fitted to the twelve moves: their in-sample and leave-one-move-out carried RMS, and the error they
   predict for the z turn, which none of them saw.
"""

from __future__ import annotations

import math
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrosim.recording import Recording
from gyrosim.units import G0

from calib import load_recording
from calib.inputs.turns import ferraris_turns, turns_for_protocol
from calib.scoring.measured_statics import StaticDetector, integrate_rk4, static_intervals
from calib.session.gravityfit import compensate_acc
from calib.session.hand.filter import kf_hand
from calib.session.hand.params import HandParams
from calib.session.model import gyro_axis_matrix
from calib.session.prepare import prepare
from calib.session.six_poses import six_pose_accelerometer

TURN_KEYS = ("x_rot", "y_rot", "z_rot")


class Session:
    """The recording, its six-pose accelerometer, its turns and the rests the harness's detector finds."""

    def __init__(self) -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.raw = load_recording("dataset:imucal_ferraris")
        poses = six_pose_accelerometer(self.raw.acc_m_s2, self.raw.meta["segments"], G0)
        self.rec = self.raw.with_signals(acc_m_s2=compensate_acc(self.raw.acc_m_s2, poses.theta()))
        self.turns = turns_for_protocol("ferraris", self.raw.meta, self.raw.t_s)
        self.rests = static_intervals(self.raw.acc_m_s2, StaticDetector.for_rate(self.raw.rate_hz))


def run(rec: Recording, turns, params: HandParams | None = None, mask: np.ndarray | None = None, **config):
    """``kf_hand`` as calib run's protocol path calls it; ``mask``: samples whose accelerometer update is skipped;
    ``config``: FilterConfig fields changed (e.g. ``prior_lever_arm_m``)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prep = prepare(rec, accelerometer="calibrated")
        if mask is not None:
            prep = replace(prep, saturated=mask if prep.saturated is None else prep.saturated | mask)
        if config:
            prep = replace(prep, config=replace(prep.config, **config))
        return kf_hand(rec, turns=turns, params=params or HandParams(misalignment=True), prepared=prep)


def gyro_parameters(cal) -> tuple[np.ndarray, ...]:
    """bias (rad/s), S, G, α (rad) of a calibration's gyro."""
    alpha = cal.value("gyro", "gyro_acc_misalignment") if cal.has("gyro", "gyro_acc_misalignment") else None
    return (cal.value("gyro", "bias"), cal.value("gyro", "scale_factor"), cal.value("gyro", "nonorthogonality"),
            alpha)


def compensate(gyro_rad_s: np.ndarray, bias, scale, nonortho, alpha) -> np.ndarray:
    """ω̂ = M_g⁻¹ (ω̃ − b) (rad/s)."""
    return (gyro_rad_s - bias) @ np.linalg.inv(gyro_axis_matrix(scale, nonortho, alpha)).T


def carried_errors(ses: Session, w_rad_s: np.ndarray) -> np.ndarray:
    """Per move: gravity carried from rest i to rest i + 1 by ``w_rad_s`` × the measured direction (rad, (moves, 3))."""
    out = []
    for (s0, e0), (s1, e1) in zip(ses.rests[:-1], ses.rests[1:]):
        g0, g1 = ses.rec.acc_m_s2[s0:e0 + 1].mean(axis=0), ses.rec.acc_m_s2[s1:e1 + 1].mean(axis=0)
        carried = integrate_rk4(w_rad_s, ses.rec.t_s, e0, s1 - 1).T @ (g0 / np.linalg.norm(g0))
        out.append(np.cross(carried, g1 / np.linalg.norm(g1)))
    return np.array(out)


def rms_deg(err: np.ndarray) -> float:
    """RMS over moves of the carried angle (°)."""
    return math.degrees(math.sqrt(float(np.mean(np.sum(err**2, axis=1)))))


def turn_errors_deg(ses: Session, w_rad_s: np.ndarray) -> list[float]:
    """Σ ω Δt about each turn's axis + 360° (°; the turns are −360°)."""
    out = []
    for axis, key in enumerate(TURN_KEYS):
        s, e = ses.raw.meta["segments"][key]["start"], ses.raw.meta["segments"][key]["end"]
        out.append(math.degrees(float(w_rad_s[s:e, axis] @ np.diff(ses.rec.t_s[s:e + 1]))) + 360.0)
    return out


def row(ses: Session, label: str, cal, gyro_rad_s: np.ndarray | None = None) -> str:
    """One line of table 1 (the figures on the full recording, whatever the variant ran on)."""
    w = compensate(ses.rec.gyro_rad_s if gyro_rad_s is None else gyro_rad_s, *gyro_parameters(cal))
    s, sd = cal.scale_factor, cal.scale_factor_std
    kt = cal.diagnostics.get("known_turns")
    inn = [t["normalised_innovation"] for t in kt["turns"]] if kt else [math.nan] * 3
    te = turn_errors_deg(ses, w)
    return (f"| {label} | {s[0]:+.4f} ± {sd[0]:.4f} | {s[1]:+.4f} ± {sd[1]:.4f} | "
            f"{s[2]:+.4f} ± {sd[2]:.4f} | {inn[0]:+.1f} {inn[1]:+.1f} {inn[2]:+.1f} | "
            f"{rms_deg(carried_errors(ses, w)):.3f} | "
            f"{te[0]:+.2f} {te[1]:+.2f} {te[2]:+.2f} | {cal.status} |")


def splice(ses: Session, cut_a: int, cut_b: int) -> tuple[Recording, object]:
    """The recording without samples [cut_a, cut_b) (two rests on the same face), re-timed, and its turns."""
    idx = np.r_[0:cut_a, cut_b:ses.rec.n]
    t = ses.rec.t_s[0] + np.arange(idx.size) / ses.rec.rate_hz
    segs = {k: {"start": v["start"] - (cut_b - cut_a), "end": v["end"] - (cut_b - cut_a)}
            for k, v in ses.raw.meta["segments"].items() if v["start"] >= cut_b}
    rec = ses.rec.with_signals(t_s=t, gyro_rad_s=ses.rec.gyro_rad_s[idx], acc_m_s2=ses.rec.acc_m_s2[idx])
    return rec, ferraris_turns(segs, t)


def sign_scaled(gyro_rad_s: np.ndarray, bias: np.ndarray, s_pos: float, s_neg: float) -> np.ndarray:
    """The raw gyro with its z rate divided by 1 + S_z⁺ where (ω̃_z − b_z) > 0, by 1 + S_z⁻ elsewhere."""
    r = gyro_rad_s - bias
    r[:, 2] = np.where(r[:, 2] > 0, r[:, 2] / (1 + s_pos), r[:, 2] / (1 + s_neg))
    return r + bias


def table_filter(ses: Session, asym: tuple[float, float]) -> None:
    """Table 1 (module docstring)."""
    rec, turns = ses.rec, ses.turns
    moving = np.ones(rec.n, bool)
    for a, b in ses.rests:
        moving[a:b + 1] = False
    rate_deg_s = np.degrees(np.linalg.norm(rec.gyro_rad_s, axis=1))
    m1, m7 = (sum(ses.rests[1]) // 2, sum(ses.rests[7]) // 2)   # rests 1 and 7: the same face (x up)
    cut, cut_turns = splice(ses, m1, m7)
    base = run(rec, turns)
    pre = sign_scaled(rec.gyro_rad_s, gyro_parameters(base)[0], *asym)
    variants = [
        ("baseline (calib run --protocol ferraris)", lambda: base),
        ("no known turns", lambda: run(rec, None)),
        ("α off", lambda: run(rec, turns, HandParams(misalignment=False))),
        ("delay state off", lambda: run(rec, turns, HandParams(misalignment=True, delay=False))),
        ("g-sensitivity on", lambda: run(rec, turns, HandParams(misalignment=True, g_sensitivity=True))),
        ("lever arm held at 0 (prior 1e-5 m)", lambda: run(rec, turns, prior_lever_arm_m=1e-5)),
        ("accelerometer updates at rests only", lambda: run(rec, turns, mask=moving)),
        ("accelerometer updates at |ω| < 100 °/s", lambda: run(rec, turns, mask=rate_deg_s > 100)),
    ] + [(f"accelerometer shifted {k:+d} sample", lambda k=k: run(rec.with_signals(
        acc_m_s2=np.roll(rec.acc_m_s2, k, axis=0)), turns)) for k in (-1, 1)] + [
        ("hand-held moves 0–6 only (no turns)", lambda: run(rec.with_signals(
            t_s=rec.t_s[:m7], gyro_rad_s=rec.gyro_rad_s[:m7], acc_m_s2=rec.acc_m_s2[:m7]), None)),
        ("moves 1–6 cut out, no turns", lambda: run(cut, None)),
        ("moves 1–6 cut out, with the turns", lambda: run(cut, cut_turns)),
        (f"z rate pre-scaled by sign (S_z⁺ {asym[0]:+.4f}, S_z⁻ {asym[1]:+.4f}), no turns",
         lambda: run(rec.with_signals(gyro_rad_s=pre), None)),
        ("… the same, with the turns", lambda: run(rec.with_signals(gyro_rad_s=pre), turns)),
    ]
    print("| variant | S_x ± σ | S_y ± σ | S_z ± σ | turn innovations x y z (σ) | carried (°) | "
          "turn errors x y z (°) | status |\n|---|---|---|---|---|---|---|---|")
    for i, (label, fn) in enumerate(variants):
        print(row(ses, label, fn(), pre if i >= len(variants) - 2 else None), flush=True)


def fit(ses: Session, moves: list[int], model, x0) -> np.ndarray:
    """Gauss–Newton of the carried errors of ``moves`` over the parameters of ``model`` (params → ω̂)."""
    x, h = np.asarray(x0, float), 1e-4
    for _ in range(5):
        e = carried_errors(ses, model(*x))[moves].ravel()
        jac = np.column_stack([(carried_errors(ses, model(*(x + h * np.eye(x.size)[k])))[moves].ravel() - e) / h
                               for k in range(x.size)])
        x = x - np.linalg.lstsq(jac, e, rcond=None)[0]
    return x


def table_moves(ses: Session) -> tuple[float, float]:
    """Table 2 (module docstring); returns the sign model's (S_z⁺, S_z⁻)."""
    base = run(ses.rec, ses.turns)
    b, s, g, a = gyro_parameters(base)
    raw, t = ses.rec.gyro_rad_s, ses.rec.t_s

    def with_sz(sz):
        return compensate(raw, b, np.r_[s[:2], sz], g, a)

    print("| move | rests | z angle (°) | peak |ω_z| (°/s) | S_z from its carried gravity | "
          "sensitivity (° per 0.01 of S_z) |\n|---|---|---|---|---|---|")
    e0, h = carried_errors(ses, with_sz(s[2])), 1e-3
    d = (carried_errors(ses, with_sz(s[2] + h)) - carried_errors(ses, with_sz(s[2] - h))) / (2 * h)
    w = with_sz(s[2])
    for j, ((_, end), (start, _)) in enumerate(zip(ses.rests[:-1], ses.rests[1:])):
        sens = math.degrees(float(np.linalg.norm(d[j]))) * 0.01
        if sens < 0.2:
            continue
        zang = math.degrees(float(w[end:start, 2] @ np.diff(t[end:start + 1])))
        best = s[2] - float(e0[j] @ d[j] / (d[j] @ d[j]))
        print(f"| {j} | {j}→{j + 1} | {zang:+.1f} | {math.degrees(np.abs(w[end:start, 2]).max()):.0f} | "
              f"{best:+.4f} | {sens:.2f} |")
    zeroed = np.r_[s[:2], 0.0]
    models = {
        "one S_z": (lambda sz: with_sz(sz), [-0.005]),
        "S_z⁺ / S_z⁻ by the sign of ω_z": (lambda sp, sn: compensate(sign_scaled(raw, b, sp, sn), b, zeroed, g, a),
                                           [-0.005, -0.005]),
        "S_z0 + c·|ω_z| (c per rad/s)": (lambda s0, c: compensate(
            np.c_[raw[:, :2], (raw[:, 2] - b[2]) / (1 + s0 + c * np.abs(raw[:, 2] - b[2])) + b[2]], b, zeroed, g, a),
            [-0.005, 0.0]),
    }
    moves = list(range(len(ses.rests) - 1))
    print("\n| z-scale model | fitted to the 12 moves | carried RMS in-sample (°) | leave-one-move-out (°) | "
          "z turn error predicted (°) | fitted to moves 0–6: moves 7–11 carried (°), z turn (°) |"
          "\n|---|---|---|---|---|---|")
    sign_fit = (math.nan, math.nan)
    for name, (model, x0) in models.items():
        x = fit(ses, moves, model, x0)
        loo = [carried_errors(ses, model(*fit(ses, [k for k in moves if k != j], model, x)))[j] for j in moves]
        early = fit(ses, moves[:7], model, x)
        late = model(*early)
        print(f"| {name} | {', '.join(f'{v:+.5f}' for v in x)} | {rms_deg(carried_errors(ses, model(*x))):.3f} | "
              f"{rms_deg(np.array(loo)):.3f} | {turn_errors_deg(ses, model(*x))[2]:+.2f} | "
              f"{rms_deg(carried_errors(ses, late)[7:]):.3f}, {turn_errors_deg(ses, late)[2]:+.2f} |")
        if name.startswith("S_z⁺"):
            sign_fit = (float(x[0]), float(x[1]))
    for sz in (s[2], -0.00172):
        print(f"\nS_z held at {sz:+.4f}: carried RMS {rms_deg(carried_errors(ses, with_sz(sz))):.3f}°, "
              f"z turn error {turn_errors_deg(ses, with_sz(sz))[2]:+.2f}°")
    return sign_fit


def main() -> int:
    """Print both tables (markdown); exit 2 without the data."""
    try:
        ses = Session()
    except Exception as exc:   # no data folder, no dataset: say so
        print(f"imucal's Ferraris session could not be loaded ({exc}); set GYROSIM_DATA", file=sys.stderr)
        return 2
    print(f"# {Path(__file__).name}: imucal's Ferraris session, S_z\n\n## Moves and z-scale models\n")
    asym = table_moves(ses)
    print("\n## kf_hand variants\n")
    table_filter(ses, asym)
    return 0


if __name__ == "__main__":
    sys.exit(main())
