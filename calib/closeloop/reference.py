"""The reference a recording offers, and the residual rows it defines.

Every reference turns a gyro error model that is *linear in its parameters*,

    y(t) = ω(t) + Σ_i R_i(t) θ_i + ε(t)        R_i = ∂y/∂θ_i of effect i (Effect.sensitivity)

into residual rows r = r₀ − J θ that least squares can fit, and says which rows belong together
(``groups``: a contiguous stretch of data, the unit of the held-out split).  Frames: all rates
in the body frame (RFU); attitudes body→navigation (ENU).

* ``truth``   – a simulation's true rate ω_true: one row per sample and axis,
                r₀ = y − ω_true, J = R (exact).
* ``optical`` – an external orientation (BROAD's optical ``opt_quat``): the rate between
                consecutive orientations, ω_{k+½} = 2·Log(q_k* ⊗ q_{k+1})·f_s, averaged over short
                blocks of ``block_s``.  Block means of the per-sample increments telescope the
                optical noise (it enters only at the block edges), so rows are block means of
                y − ω_opt; the regressors R use a low-passed ω_opt (they only scale θ).
* ``static``  – a recording at rest: the rate is zero (the Earth rate is a candidate effect);
                rows are block means of y.
* ``gravity`` – self-consistency when nothing else exists (imu_tk's idea, Tedaldi 2014): the gyro
                integrated from one rest pose to the next must turn the gravity direction
                measured at the first pose into the one measured at the second.  Rows: the tilt
                error e = ĝ_meas × ĝ_pred at each pose (rad, body frame), plus the mean rate at
                each rest (rad/s, which must be zero).  Linearised: a rate error δω(t) during the
                move rotates the predicted gravity by C(t_end ← t) δω(t) dt, so
                J_e = −[ĝ_pred×] Σ_t C(t_end ← t) R(t) Δt (Gauss–Newton, re-linearised).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal as sp_signal

from gyrosim.effects import SignalContext
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_multiply, quat_rotate, quat_to_matrix, quat_to_rotvec
from gyrosim.simulate import EARTH_FIELD_ENU_UT
from gyrosim.strapdown import integrate_gyro
from gyrosim.units import G0

__all__ = ["Reference", "RateReference", "GravityReference", "build_reference", "optical_rate", "NoReferenceError",
           "motion_specific_force", "motion_field"]


class NoReferenceError(RecordingError):
    """The recording offers no reference that can separate candidate effects (said in the report)."""


def _block_mean(x: np.ndarray, block: int) -> np.ndarray:
    """Means of consecutive blocks of ``block`` samples along axis 0 (the tail is dropped)."""
    n = (x.shape[0] // block) * block
    if block == 1:  # one sample per block: a mean would only copy (seconds on a 10-hour record)
        return x[:n]
    return x[:n].reshape((n // block, block) + x.shape[1:]).mean(axis=1)


def optical_rate(t_s: np.ndarray, quat_nb: np.ndarray) -> np.ndarray:
    """Body rate (N, 3) rad/s at the sample times from an orientation series (body→ENU, w,x,y,z).

    ω_{k+½} = 2·Log(q_k* ⊗ q_{k+1}) / Δt (body frame, sign-safe), then ω_k = ½(ω_{k−½} + ω_{k+½}) so
    that it refers to the same instant as the gyro sample k.  NaN where an orientation is missing.
    """
    d = quat_multiply(quat_conjugate(quat_nb[:-1]), quat_nb[1:])
    d = np.where(d[:, :1] < 0, -d, d)
    half = quat_to_rotvec(d) / np.diff(t_s)[:, None]
    out = np.full_like(quat_nb[:, 1:], np.nan)
    out[1:-1] = 0.5 * (half[:-1] + half[1:])
    out[0], out[-1] = half[0], half[-1]
    return out


def _fill_nan(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = x.copy()
    good = np.all(np.isfinite(x), axis=1)
    for i in range(x.shape[1]):
        out[:, i] = np.interp(t, t[good], x[good, i])
    return out


@dataclass
class Reference:
    """What every reference offers the fit (see the module docstring)."""

    kind: str
    description: str
    ctx: SignalContext          # ω_ref (for the regressors), specific force, temperature, attitude, field
    groups: np.ndarray          # (M,) held-out group of each residual row
    row_time_s: np.ndarray      # (M,) time of each row (s)
    row_axis: np.ndarray        # (M,) body axis 0..2 of each row (−1: none)
    row_unit: str               # "rad/s" or "rad"
    notes: list[str] = field(default_factory=list)
    linear: bool = True         # r is exactly linear in θ (one Gauss–Newton step)
    holdout_s: float = 4.0      # length of the alternating fit / held-out stretches (s)
    specific_force_from: str = "accelerometer"   # "truth" when ctx's specific force is the simulation's
    position_nav_m: np.ndarray | None = None     # reference position (ENU, m), when the reference has one

    def sample_groups(self) -> np.ndarray:
        """(N,) held-out group of every sample, on the same time origin as the rows' ``groups``."""
        return np.floor((self.ctx.t_s - self.row_time_s[0]) / self.holdout_s).astype(int)

    def residual(self, gyro_rad_s: np.ndarray, theta_regressors: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def jacobian(self, regressors: np.ndarray, gyro_rad_s: np.ndarray, correction: np.ndarray) -> np.ndarray:
        raise NotImplementedError


@dataclass
class RateReference(Reference):
    """Rows = block means of y − ω_ref (truth, optical or static); linear in θ."""

    block: int = 1
    block_ref_rad_s: np.ndarray | None = None   # (B, 3) block-mean reference rate
    valid_blocks: np.ndarray | None = None      # (B,) bool
    y_rad_s: np.ndarray | None = None           # measured gyro (N, 3)

    def rows_of(self, per_sample: np.ndarray) -> np.ndarray:
        """Per-sample (N, 3[, P]) → residual-row layout (M[, P]) (block means of valid blocks)."""
        b = _block_mean(per_sample, self.block)[self.valid_blocks]
        return b.reshape((-1,) + per_sample.shape[2:])

    def residual(self, gyro_rad_s: np.ndarray, correction: np.ndarray) -> np.ndarray:
        """r = rows(y − correction) − rows(ω_ref); ``correction`` = Σ R_i θ_i (N, 3)."""
        return self.rows_of(gyro_rad_s - correction) - (self.block_ref_rad_s[self.valid_blocks]).reshape(-1)

    def jacobian(self, regressors, gyro_rad_s=None, correction=None):
        return self.rows_of(regressors)


def motion_specific_force(ref: Reference) -> np.ndarray:
    """The specific force (N, 3) m/s², body frame, that the reference's *motion* explains.

    * the simulation's truth: itself;
    * a reference attitude q (body→ENU): f_b = C_bn (a_n + g e_U), gravity turned into the body frame
      plus, when the reference has a position, its acceleration a_n (Savitzky–Golay second
      derivative over 0.2 s, cubic);
    * the gravity reference: the measured accelerometer (its rest poses differ by rotations the gyro
      shows; an accelerometer drift cannot make a pose);
    * otherwise (a board at rest, no attitude): the mean measured specific force, constant.
    """
    ctx = ref.ctx
    f = np.asarray(ctx.specific_force_true_m_s2, float)
    if ref.specific_force_from == "truth" or ref.kind == "gravity":
        return f
    if ctx.quat_nb is not None and ref.kind != "static":
        acc_n = np.zeros((ctx.n, 3))
        pos = ref.position_nav_m
        ok = np.all(np.isfinite(pos), axis=1) if pos is not None else None
        if pos is not None and ok.sum() > 10:
            win = max(5, int(round(0.2 / ctx.dt_s)) | 1)
            if win < ctx.n:   # occluded samples interpolated, the acceleration there not trusted (gravity only)
                acc_n = sp_signal.savgol_filter(_fill_nan(pos, ctx.t_s), win, 3, deriv=2, delta=ctx.dt_s, axis=0)
                acc_n[~ok] = 0.0
        return quat_rotate(quat_conjugate(ctx.quat_nb), acc_n + np.array([0.0, 0.0, G0]))
    return np.broadcast_to(np.nanmean(f, axis=0), f.shape).copy()


def motion_field(ref: Reference) -> np.ndarray | None:
    """The magnetic field (N, 3) µT, body frame, that the reference's attitude explains: the mean field
    in ENU turned into the body frame (constant when there is no attitude or the board is at rest)."""
    ctx = ref.ctx
    if ctx.mag_body_ut is None:
        return None
    b = np.asarray(ctx.mag_body_ut, float)
    if ctx.quat_nb is None or ref.kind == "static":
        return np.broadcast_to(np.nanmean(b, axis=0), b.shape).copy()
    b_n = np.nanmean(quat_rotate(ctx.quat_nb, b), axis=0)
    return quat_rotate(quat_conjugate(ctx.quat_nb), np.broadcast_to(b_n, b.shape))


def _context(rec: Recording, omega_ref: np.ndarray, quat: np.ndarray | None) -> SignalContext:
    tr = rec.truth
    sf = tr.specific_force_body_m_s2 if tr is not None and tr.specific_force_body_m_s2 is not None else rec.acc_m_s2
    mag = rec.mag_ut
    if mag is None and quat is not None and rec.meta.get("schedule") is not None:
        mag = quat_rotate(quat_conjugate(quat), EARTH_FIELD_ENU_UT)  # the simulator's field
    return SignalContext(t_s=rec.t_s, omega_true_rad_s=omega_ref, specific_force_true_m_s2=np.asarray(sf),
                         temperature_c=rec.temp_c, quat_nb=quat, mag_body_ut=mag)


def _groups_for(times: np.ndarray, holdout_s: float) -> np.ndarray:
    return np.floor((times - times[0]) / holdout_s).astype(int)


def _rate_reference(kind: str, description: str, rec: Recording, ctx: SignalContext, block: int,
                    block_ref: np.ndarray, usable: np.ndarray, holdout_s: float, notes: list[str]) -> RateReference:
    """Rows of the blocks whose every sample is usable (finite reference, not saturated)."""
    valid = _block_mean(usable.astype(float), block) == 1.0
    dropped = int((~valid).sum())
    if dropped:
        notes = notes + [f"{dropped} of {valid.size} blocks dropped (missing reference or saturated samples)"]
    bt = _block_mean(rec.t_s, block)[valid]
    rows_t = np.repeat(bt, 3)
    tr = rec.truth
    return RateReference(
        kind=kind, description=description, ctx=ctx, groups=_groups_for(rows_t, holdout_s), row_time_s=rows_t,
        row_axis=np.tile(np.arange(3), bt.size), row_unit="rad/s", notes=notes, holdout_s=holdout_s,
        specific_force_from="truth" if tr is not None and tr.specific_force_body_m_s2 is not None else "accelerometer",
        position_nav_m=None if tr is None or tr.position_nav_m is None else np.asarray(tr.position_nav_m, float),
        block=block, block_ref_rad_s=block_ref, valid_blocks=valid, y_rad_s=np.asarray(rec.gyro_rad_s))


def truth_reference(rec: Recording, holdout_s: float, exclude: np.ndarray) -> RateReference:
    w = np.asarray(rec.truth.omega_body_rad_s)
    return _rate_reference("truth", "simulation truth rate (ω_true at the gyro site)", rec,
                           _context(rec, w, rec.truth.quat_nb), 1, w, ~exclude, holdout_s, [])


def optical_reference(rec: Recording, holdout_s: float, exclude: np.ndarray, block_s: float = 0.05,
                      smooth_hz: float = 15.0) -> RateReference:
    t = rec.t_s
    fs = 1.0 / float(np.median(np.diff(t)))
    q = np.asarray(rec.truth.quat_nb)
    raw = optical_rate(t, q)
    block = max(1, int(round(block_s * fs)))
    ok = np.all(np.isfinite(raw), axis=1)
    bref = _block_mean(np.where(ok[:, None], raw, 0.0), block)
    smooth = _fill_nan(raw, t)
    bb, aa = sp_signal.butter(4, smooth_hz / (fs / 2))
    smooth = sp_signal.filtfilt(bb, aa, smooth, axis=0)
    q_fill = q.copy()
    bad = ~np.all(np.isfinite(q), axis=1)
    if bad.any():  # the attitude of the regressors (Earth rate) only: hold the last good one
        idx = np.maximum.accumulate(np.where(~bad, np.arange(q.shape[0]), 0))
        q_fill = q[idx]
    notes = [
        f"optical rate from consecutive orientations, block means over {block} samples ({block / fs * 1e3:.0f} ms)",
        f"regressors use the optical rate low-passed at {smooth_hz:g} Hz (zero-phase)",
    ]
    return _rate_reference("optical", "optical orientation (opt_quat) differentiated", rec,
                           _context(rec, smooth, q_fill), block, bref, ok & ~exclude, holdout_s, notes)


def static_reference(rec: Recording, holdout_s: float, exclude: np.ndarray, block_s: float = 0.5) -> RateReference:
    fs = 1.0 / float(np.median(np.diff(rec.t_s)))
    block = max(1, int(round(block_s * fs)))
    zero = np.zeros_like(rec.gyro_rad_s)
    return _rate_reference(
        "static",
        "at rest: zero rate (the Earth rate is a candidate)",
        rec,
        _context(rec, zero, None),
        block,
        np.zeros((rec.t_s.size // block, 3)),
        ~exclude,
        holdout_s,
        [f"block means over {block} samples ({block_s:g} s)"],
    )


@dataclass
class GravityReference(Reference):
    """Rest-to-rest gravity consistency plus zero rate at rest (see the module docstring)."""

    rests: list[tuple[int, int]] = field(default_factory=list)
    gravity_dirs: np.ndarray | None = None   # (K, 3) unit gravity direction per rest (body)
    rest_sigma_rad_s: float = 1.0            # row weights: noise of a rest mean rate
    tilt_sigma_rad: float = 1.0              # row weights: noise of a tilt error
    rest_noise_rad_s: float = 1.0            # the rest noise itself (the weights before ``reweight``)
    tilt_noise_rad: float = 1.0
    rate_rows_share: int = 0
    turns: list[tuple[int, int]] = field(default_factory=list)   # protocol full turns (start, stop)

    def reweight(self, residual: np.ndarray) -> None:
        """Set the two row weights from a fitted residual (RMS of each row type, fit rows and held-out
        alike): the rest-noise σ ignores what the declared model leaves (accelerometer errors, a hand
        not quite still), so the data's own scatter weighs rate and tilt rows against each other."""
        k = self.rate_rows_share
        rate = residual[:k] * self.rest_sigma_rad_s
        tilt = residual[k:] * self.tilt_sigma_rad
        self.rest_sigma_rad_s = max(float(np.sqrt(np.mean(rate**2))), 1e-12)
        self.tilt_sigma_rad = max(float(np.sqrt(np.mean(tilt**2))), 1e-12)

    def noise_floor(self) -> float:
        """RMS over the rows of the noise-only σ in row (weighted) units: the rest noise over the
        current weights (which ``reweight`` set from the residual, structure included)."""
        k = self.rate_rows_share
        n_tilt = self.groups.size - k
        rate = (self.rest_noise_rad_s / self.rest_sigma_rad_s) ** 2
        tilt = (self.tilt_noise_rad / self.tilt_sigma_rad) ** 2
        return float(np.sqrt((k * rate + n_tilt * tilt) / max(self.groups.size, 1)))

    def split_rms(self, residual: np.ndarray, rows: np.ndarray) -> dict[str, float]:
        """Held-out RMS of the rest rate (°/s) and of the pose-to-pose tilt error (°) from weighted rows."""
        k = self.rate_rows_share
        idx = np.arange(residual.size)
        rate = residual[(idx < k) & rows] * self.rest_sigma_rad_s
        tilt = residual[(idx >= k) & rows] * self.tilt_sigma_rad
        return {
            "held_out_rest_rate_rms_deg_s": float(np.degrees(np.sqrt(np.mean(rate**2)))) if rate.size else float("nan"),
            "held_out_tilt_rms_deg": float(np.degrees(np.sqrt(np.mean(tilt**2)))) if tilt.size else float("nan"),
        }

    def _moves(self):
        for j in range(len(self.rests) - 1):
            a = (self.rests[j][0] + self.rests[j][1]) // 2
            b = (self.rests[j + 1][0] + self.rests[j + 1][1]) // 2
            yield j, a, b

    def _attitude(self, g: np.ndarray, a: int, b: int) -> np.ndarray:
        """Attitude (b − a + 1, 4) from sample a (identity) to sample b, integrating rates g (body)."""
        t = self.ctx.t_s
        return integrate_gyro(t[a : b + 1], g[a : b + 1], np.array([1.0, 0, 0, 0]))

    def residual(self, gyro_rad_s: np.ndarray, correction: np.ndarray) -> np.ndarray:
        g = gyro_rad_s - correction
        out = [g[a:b].mean(axis=0) / self.rest_sigma_rad_s for a, b in self.rests]
        for j, a, b in self._moves():
            q = self._attitude(g, a, b)
            g_pred = quat_rotate(quat_conjugate(q[-1]), self.gravity_dirs[j])
            out.append(np.cross(self.gravity_dirs[j + 1], g_pred) / self.tilt_sigma_rad)
        for a, b in self.turns:  # a protocol's full turn returns to the start attitude: Log(q) = 0
            out.append(quat_to_rotvec(self._attitude(g, a, b)[-1]) / self.tilt_sigma_rad)
        return np.concatenate(out)

    def jacobian(self, regressors: np.ndarray, gyro_rad_s: np.ndarray, correction: np.ndarray) -> np.ndarray:
        g = gyro_rad_s - correction
        rows = [regressors[a:b].mean(axis=0) / self.rest_sigma_rad_s for a, b in self.rests]
        for j, a, b in self._moves():
            q = self._attitude(g, a, b)
            rot = self._end_rotation(q, regressors, a, b)   # δφ at the end per θ
            g_pred = quat_rotate(quat_conjugate(q[-1]), self.gravity_dirs[j])
            # e = ĝ_meas × ĝ_pred; a rate change δω rotates the end body by δφ, ĝ_pred ← ĝ_pred + ĝ_pred × δφ,
            # so δe = ĝ_meas × (ĝ_pred × δφ); here δω = −R δθ (the correction grows)
            gm = self.gravity_dirs[j + 1]
            d = np.cross(gm[:, None], np.cross(g_pred[:, None], rot, axis=0), axis=0)
            rows.append(d / self.tilt_sigma_rad)   # r(θ + δ) ≈ r(θ) − J δ
        for a, b in self.turns:  # Log(q_end) grows by δφ = −rot δθ
            rows.append(self._end_rotation(self._attitude(g, a, b), regressors, a, b) / self.tilt_sigma_rad)
        return np.concatenate(rows)

    def _end_rotation(self, q: np.ndarray, regressors: np.ndarray, a: int, b: int) -> np.ndarray:
        """Σ_t C(t_end ← t) R(t) Δt: the end-attitude rotation per unit θ (3, P), given the move's
        attitude q (:meth:`_attitude`)."""
        m = np.einsum("ji,tjk->tik", quat_to_matrix(q[-1]), quat_to_matrix(q[:-1]))
        return np.einsum("tik,tkp,t->ip", m, regressors[a:b], np.diff(self.ctx.t_s[a : b + 1]))


def calibrate_accelerometer_at_rest(means_m_s2: np.ndarray):
    """Accelerometer bias b, scale s and non-orthogonality n from rest poses, |f| = g₀ at every pose
    (the gravity-magnitude reference of imu_tk, Tedaldi et al. 2014, with our vocabulary's model
    f_meas = (I + diag(s) + N(n)) f + b).  9 parameters from ≥ 12 poses, 6 (bias, scale) from ≥ 8,
    none below: the poses would not over-determine them.  Returns (f_meas ↦ f, a note)."""
    from scipy import optimize

    from gyrosim.effects import nonortho_matrix

    mags = np.linalg.norm(means_m_s2, axis=1)
    dirs = means_m_s2 / mags[:, None]
    distinct: list[np.ndarray] = []
    for d in dirs:  # poses whose gravity directions differ by more than 10°
        if all(float(d @ e) < math.cos(math.radians(10.0)) for e in distinct):
            distinct.append(d)
    k = len(distinct)
    before = (
        f"|acc| at rest {mags.min():.3f}–{mags.max():.3f} m/s² over {means_m_s2.shape[0]} rests ({k} distinct poses)"
    )
    n_par = 9 if k >= 12 else 6 if k >= 8 else 0
    if n_par == 0:
        return (lambda f: f), before + " (too few distinct poses to calibrate the accelerometer: used as measured)"

    def unpack(p):
        m = np.eye(3) + np.diag(p[3:6]) + (nonortho_matrix(p[6:9]) if n_par == 9 else 0.0)
        return p[:3], np.linalg.inv(m)

    def res(p):
        b, minv = unpack(p)
        return np.linalg.norm((means_m_s2 - b) @ minv.T, axis=1) - G0

    sol = optimize.least_squares(res, np.zeros(n_par), method="lm")
    if np.any(np.abs(sol.x[3:]) > 0.2) or np.any(np.abs(sol.x[:3]) > 0.3 * G0):
        return (lambda f: f), (before + f" (the pose fit gave an implausible accelerometer, scale "
                               f"{np.array2string(sol.x[3:6] * 100, precision=0)} %: used as measured)")
    b, minv = unpack(sol.x)
    after = np.linalg.norm((means_m_s2 - b) @ minv.T, axis=1)
    note = (f"{before}; accelerometer calibrated on them ({n_par} parameters, bias "
            f"{np.array2string(b, precision=3)} m/s², scale {np.array2string(sol.x[3:6] * 100, precision=2)} %): "
            f"|f| − g₀ RMS {np.sqrt(np.mean((mags - G0) ** 2)):.3f} → {np.sqrt(np.mean((after - G0) ** 2)):.4f} m/s²")
    return (lambda f: (f - b) @ minv.T), note


def _accelerometer_of(rec: Recording, means_m_s2: np.ndarray):
    """The accelerometer the gravity directions are read through: from a Ferraris section list's six box-face poses
    when the recording carries one (meta ``segments`` with ``x_p`` … ``z_a``: the box's right angles fix what the
    |f| = g₀ fit of a few poses cannot), else :func:`calibrate_accelerometer_at_rest`.  Returns (f ↦ f̂, a note)."""
    from calib.inputs.errors import TurnsError
    from calib.session.gravityfit import compensate_acc
    from calib.session.six_poses import six_pose_accelerometer

    try:
        theta = six_pose_accelerometer(rec.acc_m_s2, rec.meta.get("segments") or {}, G0).theta()
    except TurnsError:
        return calibrate_accelerometer_at_rest(means_m_s2)
    mags = np.linalg.norm(means_m_s2, axis=1)
    after = np.linalg.norm(compensate_acc(means_m_s2, theta), axis=1)
    return (lambda f: compensate_acc(f, theta)), (
        f"accelerometer from the section list's six box-face poses (Ferraris; bias "
        f"{np.array2string(theta[:3], precision=3)} m/s², scale {np.array2string(theta[3:6] * 100, precision=2)} %): "
        f"|f| − g₀ RMS over the {mags.size} rests {np.sqrt(np.mean((mags - G0) ** 2)):.3f} → "
        f"{np.sqrt(np.mean((after - G0) ** 2)):.4f} m/s²")


def gravity_reference(rec: Recording, holdout_s: float, exclude: np.ndarray) -> GravityReference:
    from calib.session.rest import detect_rest  # local: calib.session.rest imports nothing from here

    rest = detect_rest(rec)
    rests = [r for r in rest.index_ranges if r[1] - r[0] >= 2 and not exclude[r[0] : r[1]].any()]
    if len(rests) < 2:
        raise NoReferenceError(
            f"self-consistency needs at least two rest poses with motion between them; found {len(rests)} "
            "rest segment(s): the recording cannot separate candidate effects (record rests between rotations)")
    acc = np.asarray(rec.acc_m_s2)
    means = np.array([acc[a:b].mean(axis=0) for a, b in rests])
    acc_cal, acc_note = _accelerometer_of(rec, means)
    dirs = acc_cal(means)
    mags = np.linalg.norm(dirs, axis=1)
    dirs = dirs / mags[:, None]
    t = rec.t_s
    fs = 1.0 / float(np.median(np.diff(t)))
    gyro = np.asarray(rec.gyro_rad_s)
    sig_rate = float(np.median([gyro[a:b].std(axis=0).mean() / math.sqrt(b - a) for a, b in rests]))
    sig_acc = float(np.median([acc[a:b].std(axis=0).mean() / math.sqrt(b - a) for a, b in rests])) / G0
    # the tilt error of a move carries the noise of two gravity directions and of the rates integrated
    tilt_sigma = math.sqrt(2) * max(sig_acc, 1e-6)
    k = len(rests)
    times = [t[(a + b) // 2] for a, b in rests]
    segs = rec.meta.get("segments") or {}
    turns = [(int(v["start"]), int(min(v["end"], t.size - 1))) for name, v in segs.items()
             if isinstance(v, dict) and str(name).endswith("_rot")]
    turn_t = [t[(a + b) // 2] for a, b in turns]
    row_t = np.concatenate([np.repeat(times, 3), np.repeat(times[1:], 3), np.repeat(turn_t, 3)])
    turn_groups = [int(np.argmin(np.abs(np.array(times) - tt))) for tt in turn_t]
    groups = np.concatenate([np.repeat(np.arange(k), 3), np.repeat(np.arange(1, k), 3),
                             np.repeat(np.array(turn_groups, int), 3)])
    notes = [f"{k} rest poses (detect_rest); {k - 1} moves between them",
             f"row weights: rest mean rate σ {sig_rate:.2e} rad/s, tilt σ {tilt_sigma:.2e} rad (from the rest noise)",
             acc_note,
             "held-out unit: one rest pose and the move into it"]
    if turns:
        notes.append(f"{len(turns)} protocol full turns (meta 'segments' *_rot): the integrated rotation must be 0 mod "
                     "360°")
    gaps = np.diff(t) > 1.5 / fs
    if gaps.any():
        notes.append(f"{int(gaps.sum())} timestamp gap(s) up to {np.diff(t).max() * 1e3:.0f} ms: integrated over the "
                     "actual Δt (rate held linear across the gap)")
    ctx = _context(rec, gyro, None)
    return GravityReference(
        kind="gravity", description="self-consistency: gravity direction carried from rest pose to rest pose",
        ctx=ctx, groups=groups, row_time_s=row_t, row_axis=np.tile(np.arange(3), 2 * k - 1 + len(turns)),
        row_unit="weighted", notes=notes, linear=False, holdout_s=holdout_s, rests=list(rests), gravity_dirs=dirs,
        rest_sigma_rad_s=max(sig_rate, 1e-9), tilt_sigma_rad=tilt_sigma, rest_noise_rad_s=max(sig_rate, 1e-9),
        tilt_noise_rad=tilt_sigma, rate_rows_share=3 * k, turns=turns)


def build_reference(rec: Recording, holdout_s: float = 4.0, prefer: str | None = None,
                    exclude: np.ndarray | None = None) -> Reference:
    """The best reference the recording has: truth rate > optical orientation > (static | gravity).

    ``exclude``: samples to leave out (saturated: their true value is unknown); rate references
    drop the blocks that hold one, the gravity reference the rests that do."""
    exclude = np.zeros(rec.t_s.size, bool) if exclude is None else np.asarray(exclude, bool)
    tr = rec.truth
    kinds = []
    if tr is not None and tr.omega_body_rad_s is not None:
        kinds.append("truth")
    if tr is not None and tr.quat_nb is not None:
        kinds.append("optical")
    moving = np.percentile(np.linalg.norm(rec.gyro_rad_s - np.median(rec.gyro_rad_s, axis=0), axis=1), 99) > 0.2
    kinds.append("gravity" if moving else "static")
    kind = prefer or kinds[0]
    if kind not in ("truth", "optical", "static", "gravity"):
        raise RecordingError(f"unknown reference {kind!r}; choose truth, optical, static or gravity")
    if kind not in kinds and kind != "gravity":
        raise RecordingError(f"this recording has no {kind} reference; it offers {', '.join(kinds)}")
    build = {"truth": truth_reference, "optical": optical_reference, "static": static_reference,
             "gravity": gravity_reference}[kind]
    return build(rec, holdout_s, exclude)
