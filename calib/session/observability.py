"""Observability of the Zhou 2020 filter (§4): stripped observability matrix (SOM) per segment.

For the model of :mod:`calib.session.model` (state [φ, S, G], continuous A = F/Δt, H = [[g_up×], 0, 0]),
the paper's observability test stacks N₀ = H and N₁ = N₀ A + dN₀/dt = H A (eq. 15–16; H is
constant).  For a rotation at rate ω (body) with attitude C:

    H A = [0, −[g_up×] C M⁻¹ diag(ω), −[g_up×] C M⁻¹ J_G(ω)]

so a parameter is observable in a segment when its column of H A has a horizontal component:
rotating about the vertical z excites Gx, Gy (|column| = g|ω|), about a horizontal axis one scale
factor together with two non-orthogonalities (Zhou Table 5).

Over a segment the SOM stacks [N₀; N₁] at every sample and divides by √n, so its singular values
are RMS values over the segment (g for the two levelling rows, g·ω_RMS for an excited direction);
the paper evaluates one instant at an unstated rate, so its Tables 10–11 values (8.52 for a z
rotation) match ours in structure, not digit for digit.  "Without" a set of states deletes their
columns: the singular values that collapse show what those states contributed (Tables 10–11).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.rotations import quat_conjugate, quat_rotate, quat_to_matrix, skew
from gyrosim.schedule import Schedule
from gyrosim.units import G0

from calib.session.gravityfit import GravityFit, gravity_regressor
from calib.session.model import STATE_NAMES, StateLayout, jacobian_nonorthogonality

__all__ = ["som", "parameter_gram", "SegmentObservability", "segment_observability", "unobservable_states",
           "unobservable_parameters", "JointObservability", "joint_observability", "filter_observability",
           "check_observability", "missing_poses", "pose_name", "schedule_accelerometer_observability"]


def som(omega_body_rad_s: np.ndarray, quat_nb: np.ndarray, gravity_m_s2: float = G0,
        m_inv: np.ndarray | None = None) -> np.ndarray:
    """Normalised stripped observability matrix (6n × 9 stacked [N₀; N₁] / √n)."""
    w = np.asarray(omega_body_rad_s, float)
    c = quat_to_matrix(np.asarray(quat_nb, float))
    n = w.shape[0]
    m_inv = np.eye(3) if m_inv is None else m_inv
    gx = skew(np.array([0.0, 0.0, gravity_m_s2]))
    n0 = np.hstack([gx, np.zeros((3, 6))])
    rows = np.empty((n, 6, 9))
    rows[:, :3] = n0
    cm = np.einsum("nij,jk->nik", c, m_inv)
    rows[:, 3:, 0:3] = 0.0
    rows[:, 3:, 3:6] = -np.einsum("ij,njk->nik", gx, cm * w[:, None, :])
    jg = np.stack([jacobian_nonorthogonality(wk) for wk in w])
    rows[:, 3:, 6:9] = -np.einsum("ij,njk,nkl->nil", gx, cm, jg)
    return rows.reshape(6 * n, 9) / np.sqrt(n)


def _names_to_cols(names: tuple[str, ...]) -> list[int]:
    return [STATE_NAMES.index(n) for n in names]


def unobservable_states(matrix: np.ndarray, rel_tol: float = 1e-3, share: float = 0.5) -> list[str]:
    """States whose unit vector lies mostly (> ``share``) in the SOM's numerical null space."""
    _, sv, vt = np.linalg.svd(matrix, full_matrices=True)
    sv_full = np.concatenate([sv, np.zeros(vt.shape[0] - sv.size)])
    null = vt[sv_full < rel_tol * sv_full.max()]
    if null.size == 0:
        return []
    proj = np.sum(null**2, axis=0)  # |P_null e_i|²
    return [STATE_NAMES[i] for i in range(vt.shape[1]) if proj[i] > share**2]


@dataclass(frozen=True)
class SegmentObservability:
    """One schedule segment: SOM singular values (full and with states removed) and the verdict."""

    label: str
    kind: str
    singular_values: np.ndarray
    observable: tuple[str, ...]
    without: dict[tuple[str, ...], np.ndarray]


def segment_observability(schedule: Schedule, rate_hz: float = 100.0,
                          without: dict[int, tuple[str, ...]] | None = None) -> list[SegmentObservability]:
    """SOM per segment of the commanded (ideal-hand) motion of ``schedule``.

    ``without``: {segment index: state names to delete} for the Tables 10–11 comparison.
    """
    out = []
    for i, seg in enumerate(schedule.segments):
        t0, t1 = schedule.boundaries_s[i], schedule.boundaries_s[i + 1]
        t = np.arange(t0, t1, 1.0 / rate_hz)
        kin = schedule.kinematics(t)
        mat = som(kin.omega_body_rad_s, kin.quat_nb)
        sv = np.linalg.svd(mat, compute_uv=False)
        params_unobs = set(unobservable_states(mat))
        observable = tuple(n for n in STATE_NAMES[3:] if n not in params_unobs)
        extra = {}
        for names in (without or {}).get(i, ()):
            keep = [j for j in range(9) if j not in _names_to_cols(names)]
            extra[names] = np.linalg.svd(mat[:, keep], compute_uv=False)
        out.append(SegmentObservability(seg.label or seg.kind, seg.kind, sv, observable, extra))
    return out


def parameter_gram(omega_body_rad_s: np.ndarray, gravity_body: np.ndarray) -> np.ndarray:
    """Gram matrix (6 × 6) of the SOM's parameter block, from body-frame quantities only.

    N₀ rows act on φ only and N₁ rows on (S, G) only, so the SOM's Gram matrix is block-diagonal;
    in the parameter block the attitude cancels, [g×] C = C [g_b×] with g_b the gravity in the
    body frame (what a resting accelerometer reads):  Σ_k X_kᵀ [g_b×]ᵀ [g_b×] X_k / n,
    X_k = [diag(ω_k), J_G(ω_k)].  No attitude integration is needed.
    """
    w = np.asarray(omega_body_rad_s, float)
    gb = np.asarray(gravity_body, float)
    x = np.concatenate(
        [np.einsum("ij,nj->nij", np.eye(3), w), np.stack([jacobian_nonorthogonality(v) for v in w])], axis=2
    )
    rows = np.einsum("nij,njk->nik", skew(gb), x)  # (n, 3, 6)
    return np.einsum("nij,nik->jk", rows, rows) / w.shape[0]


def unobservable_parameters(
    gram: np.ndarray, gravity_m_s2: float = G0, rel_tol: float = 1e-2, share: float = 0.5
) -> list[str]:
    """Filter parameters (S_*, G_*) mostly in the null space of ``gram``: eigenvalues below
    (rel_tol · g)², i.e. less excitation than a rotation of rel_tol rad/s gives."""
    vals, vecs = np.linalg.eigh(gram)
    null = vecs[:, vals < (rel_tol * gravity_m_s2) ** 2]
    if null.size == 0:
        return []
    proj = np.sum(null**2, axis=1)
    return [STATE_NAMES[3 + i] for i in range(6) if proj[i] > share**2]


# ---------------------------------------------------------------------------------------------
# Joint observability of gyro and accelerometer parameters (the filter's own information)
# ---------------------------------------------------------------------------------------------
#
# With accelerometer states the attitude no longer cancels (H carries Ĉ for the accelerometer
# columns), so the verdict comes from the information the filter itself gathers along the
# session: the posterior covariance P of the parameter blocks, normalised by the prior,
# P̃ = D⁻¹ P D⁻¹ (D = prior σ).  An eigen-direction of P̃ with eigenvalue λ kept ≥ 0.25 of its prior
# variance (σ along it > half the prior σ) is a combination of parameters this motion did not
# determine; the parameters loading it (share ≥ 0.1 of the direction) are named.  λ > 0.8: no
# information at all ("unobservable"); otherwise "weakly observable".  The heading and the gyro
# bias (whose prior is the static average, already data) are left out.

@dataclass(frozen=True)
class JointObservability:
    """Per parameter: posterior σ / prior σ; the poorly determined combinations and their names."""

    names: tuple[str, ...]
    ratio: np.ndarray
    unobservable: tuple[str, ...]
    weak: tuple[str, ...]
    directions: tuple[tuple[float, tuple[str, ...]], ...]


def joint_observability(p_post: np.ndarray, p_prior: np.ndarray, names: tuple[str, ...], keep: np.ndarray,
                        weak_eig: float = 0.25, none_eig: float = 0.8, share: float = 0.1) -> JointObservability:
    """Verdict of the module section above on the states ``keep`` (boolean mask over ``names``)."""
    idx = np.flatnonzero(keep)
    d = np.sqrt(np.diag(p_prior)[idx])
    pt = p_post[np.ix_(idx, idx)] / np.outer(d, d)
    vals, vecs = np.linalg.eigh(0.5 * (pt + pt.T))
    ratio = np.sqrt(np.clip(np.diag(pt), 0, None))
    sel_names = tuple(names[i] for i in idx)
    unobs, weak, dirs = [], [], []
    for lam, v in sorted(zip(vals, vecs.T), key=lambda x: -x[0]):
        if lam < weak_eig:
            break
        who = tuple(sel_names[i] for i in np.flatnonzero(v**2 >= share))
        dirs.append((float(lam), who))
        (unobs if lam > none_eig else weak).extend(who)
    unobs_t = tuple(dict.fromkeys(unobs))
    weak_t = tuple(n for n in dict.fromkeys(weak) if n not in unobs_t)
    return JointObservability(sel_names, ratio, unobs_t, weak_t, tuple(dirs))


def pose_name(u: np.ndarray) -> str:
    """'x up', 'y down', 'x and z up at 45°', 'x up, z down at 45°' for a gravity direction u (body)."""
    parts = [(ax, "up" if c > 0 else "down") for ax, c in zip("xyz", u) if abs(c) > 1e-9]
    if len(parts) == 1:
        return f"{parts[0][0]} {parts[0][1]}"
    (a1, s1), (a2, s2) = parts
    return f"{a1} and {a2} {s1} at 45°" if s1 == s2 else f"{a1} {s1}, {a2} {s2} at 45°"


def missing_poses(names: list[str], f_hat_windows: np.ndarray | None, within_deg: float = 20.0) -> list[str]:
    """Rest poses that would determine the named accelerometer parameters from |f| = g (Ferraris 1995's
    six faces, plus the 45° poses Tedaldi 2014 adds for the axis couplings), leaving out the poses the
    session already holds (a quasi-static window's gravity within ``within_deg`` of it).

    Rules from the regressor of :func:`calib.session.gravityfit.gravity_regressor`: b_i and S_i separate only
    with axis i both up and down (uᵢ changes sign, uᵢ² does not); G_x couples y and z, so it needs
    gravity between them (u_y u_z ≠ 0), G_y between x and z, G_z between x and y."""
    want: list[np.ndarray] = []
    for n in names:
        block, ax = n.split("_")
        i = "xyz".index(ax)
        if block in ("ba", "Sa"):
            for s in (1.0, -1.0):
                u = np.zeros(3)
                u[i] = s
                want.append(u)
        elif block == "Ga":
            j, k = [m for m in range(3) if m != i]
            u = np.zeros(3)
            u[j], u[k] = 1.0, 1.0
            want.append(u / np.linalg.norm(u))
    have = np.zeros((0, 3))
    if f_hat_windows is not None and len(f_hat_windows):
        f = np.asarray(f_hat_windows, float)
        have = f / np.linalg.norm(f, axis=1, keepdims=True)
    out: list[str] = []
    cos = np.cos(np.radians(within_deg))
    for u in want:
        name = pose_name(u)
        if name not in out and not (have.size and np.any(have @ u > cos)):
            out.append(name)
    return out


def schedule_accelerometer_observability(schedule: Schedule, rate_hz: float = 100.0, sigma_f_m_s2: float = 0.03,
                                         gravity_m_s2: float = G0,
                                         prior_sigma: np.ndarray | None = None) -> tuple[JointObservability, list[str]]:
    """What a schedule's commanded (ideal-hand) motion tells the accelerometer's nine parameters through
    |f| = g (the first stage of ``calib run``, :mod:`calib.session.gravityfit`): the posterior of the Gauss–Newton
    information at the truth, per-sample noise ``sigma_f_m_s2`` (default: the MPU-9250's 3 mg at 100 Hz),
    against the prior (±1 m/s² bias, ±5 % scale and axis errors); the verdict of
    :func:`joint_observability` and the rest poses :func:`missing_poses` would add."""
    t = np.arange(0.0, schedule.duration_s, 1.0 / rate_hz)
    kin = schedule.kinematics(t)
    f = quat_rotate(quat_conjugate(kin.quat_nb), np.array([0.0, 0.0, gravity_m_s2]))
    prior = np.array([1.0] * 3 + [0.05] * 6) if prior_sigma is None else np.asarray(prior_sigma, float)
    rows = gravity_regressor(f)
    info = rows.T @ rows / sigma_f_m_s2**2 + np.diag(1.0 / prior**2)
    names = tuple(f"{blk}_{ax}" for blk in ("ba", "Sa", "Ga") for ax in "xyz")
    verdict = joint_observability(np.linalg.inv(info), np.diag(prior**2), names, np.ones(9, bool))
    step = max(1, int(round(0.1 * rate_hz)))
    return verdict, missing_poses(list(verdict.unobservable + verdict.weak), f[::step])


def filter_observability(layout: StateLayout, p_post: np.ndarray, p0: np.ndarray,
                         gravity_fit: GravityFit | None) -> JointObservability:
    """What a calibration run determined: the gyro's S, G from the filter's information (posterior ``p_post`` (n, n)
    against the prior ``p0``), the accelerometer from the |f| = g stage's (``gravity_fit``, when it is estimated) — a
    session whose gravity directions do not determine the accelerometer is refused (:func:`check_observability`),
    whatever the filter's horizontal rows would add: the criterion of Ferraris and Tedaldi."""
    keep = np.array([blk in ("gyro_scale", "gyro_nonorth") for blk in layout.blocks for _ in range(3)])
    gyro = joint_observability(p_post, p0, layout.names, keep)
    if gravity_fit is None:
        return gyro
    gf = gravity_fit
    names = tuple(f"{blk}_{ax}" for blk in ("ba", "Sa", "Ga") for ax in "xyz")
    acc = joint_observability(gf.covariance, np.diag(gf.prior_sigma**2), names, np.ones(9, bool))
    return JointObservability(gyro.names + acc.names, np.concatenate([gyro.ratio, acc.ratio]),
                              gyro.unobservable + acc.unobservable, gyro.weak + acc.weak,
                              gyro.directions + acc.directions)


def _label(name: str) -> str:
    """'Sa_x' → 'accelerometer S_x'; the gyro's names stay the paper's ('S_x', 'G_y')."""
    block, ax = name.split("_")
    return {"S": f"S_{ax}", "G": f"G_{ax}", "ba": f"accelerometer b_{ax}", "Sa": f"accelerometer S_{ax}",
            "Ga": f"accelerometer G_{ax}"}[block]


def check_observability(obs: JointObservability, windows_f_hat: np.ndarray | None, warnings: list[str]) -> None:
    """An accelerometer the session cannot separate from the gyro errors is refused (RecordingError naming the rest
    poses to add, from the quasi-static windows' gravity directions ``windows_f_hat``); gyro S, G the motion left
    undetermined are named in ``warnings`` (appended)."""
    acc_names = [n for n in obs.unobservable + obs.weak if n.split("_")[0] in ("ba", "Sa", "Ga")]
    if acc_names:
        poses = missing_poses(acc_names, windows_f_hat)
        raise RecordingError(
            "this session cannot separate the accelerometer from the gyro errors: "
            f"{', '.join(_label(n) for n in acc_names)} "
            "stay undetermined (posterior σ above half the prior). Add rest poses of ≥ 2 s with gravity along: "
            f"{'; '.join(poses) if poses else 'more distinct directions (Tedaldi 2014: ≥ 9, well spread)'} — or slow "
            "rotations through them — or pass --accelerometer calibrated if the accelerometer is calibrated already"
        )
    gyro_unobs = [n for n in obs.unobservable if n.split("_")[0] in ("S", "G")]
    gyro_weak = [n for n in obs.weak if n.split("_")[0] in ("S", "G")]
    if gyro_unobs:
        warnings.append(
            f"unobservable: {', '.join(gyro_unobs)}: the recording's motion leaves them undetermined (posterior σ "
            "within 90 % of the prior; Zhou 2020 §4); add rotations about horizontal axes (scale factors) and about "
            "the vertical (non-orthogonality), Zhou 2020 Table 5")
    if gyro_weak:
        warnings.append(
            f"weakly observable: {', '.join(gyro_weak)} (posterior σ > half the prior): the motion barely excited "
            "them for this noise level; rotate longer or faster about the axes Zhou 2020 Table 5 names")
