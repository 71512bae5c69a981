"""The imperfect human hand: named, documented, severity-scaled deviations from the schedule.

Four imperfections, each with the disturbance it produces at the IMU (see :meth:`Hand.expected_disturbance`):

* **Physiological tremor** — band-limited (default 8–12 Hz) random translation of the rotation
  centre with acceleration RMS ``tremor_acc_rms_m_s2`` (magnitude of the 3-vector) and random
  rotation with rate RMS ``tremor_rate_rms_rad_s``.  Postural hand tremor of healthy adults peaks
  at 0.0015–0.035 g (modal 0.01 g) at the dominant frequency (Wade, Gresty & Findley, "A normative
  study of postural tremor of the hand", Arch. Neurol. 39(6):358–362, 1982,
  doi:10.1001/archneur.1982.00510180036009); a sinusoid of peak a has RMS a/√2.  The rotational
  part is the same tremor seen as rotation of the hand about the wrist at lever arm
  ℓ = 0.08 m: rate RMS = acc RMS / (2π f_c ℓ) with f_c = 10 Hz.
* **Sway** — slow (default 0.2–1 Hz) random translation of the rotation centre by the arm, with
  acceleration RMS ``sway_acc_rms_m_s2``.  For a flat acceleration spectrum on [f₁, f₂] the
  displacement RMS is σ_a · √((f₁⁻³ − f₂⁻³) / (3 (2π)⁴ (f₂ − f₁))) (0.18 σ_a s² on 0.2–1 Hz), so
  0.02 m/s² is 3.6 mm of drift: an engineering estimate of an unsupported forearm, not a
  literature value.
* **Rotation centre away from the sensor** — the board turns about a point
  ``pivot_offset_m`` (body frame, m, from the accelerometer site); the accelerometer then feels
  a = α × r + ω × (ω × r), the centripetal part ω² r.  Hand anthropometry (Winter, *Biomechanics
  and Motor Control of Human Movement*, 4th ed., Table 4.1: hand length 0.108 H) puts the wrist
  7–10 cm behind a palm-held board.
* **Axis wobble** — the actual rotation axis is tilted from the commanded body axis by a slowly
  varying (default 0.1–1 Hz) small rotation β(t) with RMS tilt ``axis_wobble_rms_deg``; the rate
  disturbance is β × ω, RMS = tilt_rms · RMS|ω|.  The attitude is the integral of the disturbed
  rate, so a wobbly hand also ends each segment slightly off the commanded attitude, as a real one
  does.  The size (1–4°) is an engineering estimate.

Presets (``ideal``, ``steady``, ``typical``, ``shaky``) are TOML files in
``gyrosim/presets/hands/``; users can pass their own TOML path.  Every random draw comes from the
``numpy.random.Generator`` passed by the caller; the four imperfections draw from independent
child streams (``rng.spawn``), so switching one off does not change the others.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy import fft as sp_fft

from ._presets import builtin_names, load_named_toml
from .errors import PresetError
from .rotations import (
    cross3,
    quat_cumulative_product,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    right_jacobian_apply,
)
from .schedule import Schedule

__all__ = [
    "Hand",
    "HandMotion",
    "HandNoise",
    "IMPERFECTIONS",
    "band_limited_noise",
    "hand_preset_names",
    "load_hand",
]


def band_limited_noise(
    n: int,
    dt_s: float,
    band_hz: tuple[float, float],
    rms: float,
    rng: np.random.Generator,
    *,
    dims: int = 3,
    orders: tuple[int, ...] = (0,),
) -> list[np.ndarray]:
    """Gaussian noise with a flat spectrum on ``band_hz``, synthesised in the frequency domain.

    The signal ``x`` (shape (n, dims)) has expected squared magnitude E|x|² = rms² (the vector
    magnitude, split equally over ``dims`` axes).  With in-band rFFT bins X_k = c (g₁ + i g₂)/√2
    (g ~ N(0, 1)) over a record of m ≥ n points (m = ``scipy.fft.next_fast_len(n)``, then cut to
    n), irfft gives E[x_t²] = 2 K c² / m² for K in-band bins, hence c = σ m / √(2K) with
    σ = rms / √dims.

    ``orders`` selects what is returned, in that order: 0 is x, +j its j-th time derivative,
    −j its j-th time integral (X_k (i 2π f)^j, exact and zero-mean since the band excludes DC).
    A tremor acceleration thus comes with the velocity and displacement that produce it.
    """
    if rms < 0 or not math.isfinite(rms):
        raise PresetError(f"an RMS amplitude must be finite and >= 0, got {rms}")
    f_lo, f_hi = band_hz
    m = sp_fft.next_fast_len(n, real=True)
    freqs = np.fft.rfftfreq(m, dt_s)
    in_band = (freqs >= f_lo) & (freqs <= f_hi) & (freqs > 0)
    k = int(in_band.sum())
    if rms == 0.0:
        return [np.zeros((n, dims)) for _ in orders]
    if k == 0:
        raise PresetError(
            f"band {band_hz} Hz holds no frequency bin of a {m * dt_s:.3g} s record at "
            f"{1 / dt_s:.6g} Hz: lengthen the session or widen the band"
        )
    sigma = rms / math.sqrt(dims)
    c = sigma * m / math.sqrt(2.0 * k)
    spec = np.zeros((freqs.size, dims), dtype=complex)
    g = rng.standard_normal((k, dims, 2))
    spec[in_band] = c * (g[..., 0] + 1j * g[..., 1]) / math.sqrt(2.0)
    jw = np.where(in_band, 2j * np.pi * freqs, 1.0)[:, None]
    return [sp_fft.irfft(spec * jw**order, n=m, axis=0)[:n] for order in orders]


@dataclass(frozen=True)
class HandNoise:
    """The random draws of one session on the physics grid (zeros for an ideal hand).

    ``beta_rad`` is the wobble rotation vector (body frame) and ``beta_dot_rad_s`` its rate;
    ``omega_tremor_rad_s`` / ``omega_dot_tremor_rad_s2`` the rotational tremor (body frame);
    ``pivot_*`` the tremor + sway translation of the rotation centre (navigation frame, m).
    """

    beta_rad: np.ndarray
    beta_dot_rad_s: np.ndarray
    omega_tremor_rad_s: np.ndarray
    omega_dot_tremor_rad_s2: np.ndarray
    pivot_m: np.ndarray
    pivot_velocity_m_s: np.ndarray
    pivot_acceleration_m_s2: np.ndarray

    @property
    def rotates(self) -> bool:
        """True if the hand's rate deviates from the schedule (wobble or rotational tremor)."""
        return bool(np.any(self.beta_rad) or np.any(self.omega_tremor_rad_s))

    def rows(self, a: int, b: int) -> "HandNoise":
        return HandNoise(*(getattr(self, f)[a:b] for f in self.__dataclass_fields__))


@dataclass(frozen=True)
class HandMotion:
    """The commanded rigid-body motion of the hand (what its muscles try to do), sampled at ``t_s``.

    Frames: ``quat_nb`` body (RFU) → navigation (ENU), (w, x, y, z).  ``omega_body_rad_s`` and
    ``omega_dot_body_rad_s2`` in the body frame.  The rotation centre ("pivot") is a point fixed
    in the body at ``pivot_body_m`` (body frame, relative to the accelerometer site); its
    navigation-frame path relative to its start is ``pivot_m`` with derivatives.
    ``omega_schedule_body_rad_s`` is the schedule's rate alone (no imperfection).
    """

    t_s: np.ndarray
    quat_nb: np.ndarray
    omega_body_rad_s: np.ndarray
    omega_dot_body_rad_s2: np.ndarray
    omega_schedule_body_rad_s: np.ndarray
    pivot_body_m: np.ndarray
    pivot_m: np.ndarray
    pivot_velocity_m_s: np.ndarray
    pivot_acceleration_m_s2: np.ndarray
    segment_index: np.ndarray

    def select(self, index: slice | np.ndarray) -> "HandMotion":
        """The steps picked by ``index`` (a slice or index array; ``pivot_body_m``, a constant,
        is kept whole)."""
        return HandMotion(**{f: (v if f == "pivot_body_m" else v[index]) for f, v in vars(self).items()})


@dataclass(frozen=True)
class Hand:
    """Severity-scaled hand imperfections. Units are in the field names; see module docstring."""

    name: str = "custom"
    description: str = ""
    tremor_acc_rms_m_s2: float = 0.0
    tremor_rate_rms_rad_s: float = 0.0
    tremor_band_hz: tuple[float, float] = (8.0, 12.0)
    sway_acc_rms_m_s2: float = 0.0
    sway_band_hz: tuple[float, float] = (0.2, 1.0)
    pivot_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis_wobble_rms_deg: float = 0.0
    wobble_band_hz: tuple[float, float] = (0.1, 1.0)
    sources: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for key in ("tremor_acc_rms_m_s2", "tremor_rate_rms_rad_s", "sway_acc_rms_m_s2", "axis_wobble_rms_deg"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise PresetError(f"hand {self.name!r}: {key} = {v!r} must be a finite number >= 0")
        for key in ("tremor_band_hz", "sway_band_hz", "wobble_band_hz"):
            lo, hi = getattr(self, key)
            if not (0 < lo < hi and math.isfinite(hi)):
                raise PresetError(f"hand {self.name!r}: {key} = {(lo, hi)} must satisfy 0 < low < high")
        if len(self.pivot_offset_m) != 3 or not all(map(math.isfinite, self.pivot_offset_m)):
            raise PresetError(f"hand {self.name!r}: pivot_offset_m must be 3 finite numbers (m)")

    @property
    def is_ideal(self) -> bool:
        return (
            self.tremor_acc_rms_m_s2 == 0
            and self.tremor_rate_rms_rad_s == 0
            and self.sway_acc_rms_m_s2 == 0
            and self.axis_wobble_rms_deg == 0
            and not any(self.pivot_offset_m)
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def without(self, *parts: str) -> "Hand":
        """A copy of the hand with the named imperfections switched off (:data:`IMPERFECTIONS`: ``tremor``,
        ``tremor_rotation``, ``sway``, ``pivot``, ``wobble``), the others unchanged — for a robustness test of an
        estimator against each imperfection alone.  The child random streams are independent (module
        docstring), so a variant simulated with the same seed keeps the other imperfections' draws exactly.
        The name records what was removed (``shaky-without-wobble``)."""
        unknown = [p for p in parts if p not in IMPERFECTIONS]
        if unknown or not parts:
            raise PresetError(f"hand {self.name!r}: cannot switch off {unknown or 'nothing'}; name one or more of "
                              f"{sorted(IMPERFECTIONS)}")
        zero = {key: (0.0, 0.0, 0.0) if key == "pivot_offset_m" else 0.0 for p in parts for key in IMPERFECTIONS[p]}
        return replace(self, name=f"{self.name}-without-{'-'.join(parts)}", **zero,
                       description=f"{self.description} (switched off: {', '.join(parts)})".strip())

    # ------------------------------------------------------------------ motion
    def draw_noise(self, n: int, dt_s: float, rng: np.random.Generator) -> HandNoise:
        """Draw this hand's random imperfections for ``n`` physics steps of ``dt_s`` (s).

        The four imperfections use independent child streams of ``rng`` (``rng.spawn(4)``).
        Wobble: isotropic β with per-axis σ; its tilt (component ⟂ ω) has E|β⊥|² = 2σ², so
        σ = tilt/√2, i.e. |β| RMS = tilt · √(3/2).
        """
        rng_tremor_lin, rng_tremor_rot, rng_sway, rng_wobble = rng.spawn(4)
        wobble = math.radians(self.axis_wobble_rms_deg) * math.sqrt(1.5)
        beta, beta_dot = band_limited_noise(n, dt_s, self.wobble_band_hz, wobble, rng_wobble, orders=(0, 1))
        w_tr, wd_tr = band_limited_noise(
            n, dt_s, self.tremor_band_hz, self.tremor_rate_rms_rad_s, rng_tremor_rot, orders=(0, 1)
        )
        a_t, v_t, p_t = band_limited_noise(
            n, dt_s, self.tremor_band_hz, self.tremor_acc_rms_m_s2, rng_tremor_lin, orders=(0, -1, -2)
        )
        a_s, v_s, p_s = band_limited_noise(
            n, dt_s, self.sway_band_hz, self.sway_acc_rms_m_s2, rng_sway, orders=(0, -1, -2)
        )
        return HandNoise(beta, beta_dot, w_tr, wd_tr, p_t + p_s, v_t + v_s, a_t + a_s)

    def motion_chunk(
        self,
        schedule: Schedule,
        t_s: np.ndarray,
        noise: HandNoise,
        previous: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> HandMotion:
        """Commanded motion on consecutive physics steps ``t_s`` (s) with their ``noise`` rows.

        Body rate (body frame): ω = Exp(β) ω_s + ω_tr, and analytically
        ω̇ = Exp(β) (ω̇_s + (J_r(β) β̇) × ω_s) + ω̇_tr  (d/dt Exp(β) = Exp(β)[J_r(β) β̇ ×]).
        Attitude: the schedule's closed form when the rate is the schedule's; otherwise
        q_{k+1} = q_k ⊗ Exp(½(ω_k + ω_{k+1}) Δt) (local error O(Δt³)), continued from
        ``previous`` = (attitude, rate) of the step before this chunk, or from the schedule's
        initial attitude.
        """
        t = np.asarray(t_s, dtype=float)
        kin = schedule.kinematics(t)
        omega_s = kin.omega_body_rad_s
        if noise.rotates:
            rot_beta = quat_from_rotvec(noise.beta_rad)
            cross = cross3(right_jacobian_apply(noise.beta_rad, noise.beta_dot_rad_s), omega_s)
            omega = quat_rotate(rot_beta, omega_s) + noise.omega_tremor_rad_s
            omega_dot = quat_rotate(rot_beta, kin.omega_dot_body_rad_s2 + cross) + noise.omega_dot_tremor_rad_s2
            if previous is None:
                q0, w_prev = np.asarray(schedule.initial_quat_nb, dtype=float), omega[:1]
                first = q0[None]
                increments = 0.5 * (omega[1:] + omega[:-1])
            else:
                q0, w_prev = previous
                first = np.empty((0, 4))
                increments = 0.5 * (omega + np.concatenate([w_prev[None], omega[:-1]]))
            dt = float(t[1] - t[0]) if t.size > 1 else float(schedule.boundaries_s[-1])
            steps = np.concatenate([first, quat_from_rotvec(increments * dt)])
            quat = quat_cumulative_product(steps)
            if previous is not None:
                quat = quat_normalize(quat_multiply(q0, quat))
        else:
            omega, omega_dot, quat = omega_s, kin.omega_dot_body_rad_s2, kin.quat_nb
        return HandMotion(
            t_s=t,
            quat_nb=quat,
            omega_body_rad_s=omega,
            omega_dot_body_rad_s2=omega_dot,
            omega_schedule_body_rad_s=omega_s,
            pivot_body_m=np.asarray(self.pivot_offset_m, dtype=float),
            pivot_m=kin.translation_m + noise.pivot_m,
            pivot_velocity_m_s=kin.velocity_m_s + noise.pivot_velocity_m_s,
            pivot_acceleration_m_s2=kin.acceleration_m_s2 + noise.pivot_acceleration_m_s2,
            segment_index=kin.segment_index,
        )

    def motion(self, schedule: Schedule, t_s: np.ndarray, rng: np.random.Generator) -> HandMotion:
        """Whole-session commanded motion on a uniform grid ``t_s`` (s); see :meth:`motion_chunk`."""
        t = np.asarray(t_s, dtype=float)
        noise = self.draw_noise(t.size, float(t[1] - t[0]), rng)
        return self.motion_chunk(schedule, t, noise)

    # ------------------------------------------------------------------ prediction
    def expected_disturbance(self, schedule: Schedule, rate_hz: float = 1000.0) -> dict[str, float]:
        """Predicted RMS disturbances at the IMU over ``schedule`` (the documented values).

        Returns (all RMS of the vector magnitude over the whole session):

        * ``external_acc_rms_m_s2`` — non-gravity acceleration at the accelerometer site,
          √(a_tremor² + a_sway² + a_pivot² + a_tremor-rot²), independent terms adding in power.
          a_pivot is evaluated exactly on the commanded kinematics: |α × r + ω × (ω × r)| with
          r = −pivot_offset (accelerometer relative to the rotation centre).  The rotational tremor
          acting at lever |r| adds (2π f)² ω_tr² |r|² ⟨sin²⟩ ≈ ⅔ (2π f_c)² ω_tr² |r|², f_c the band
          centre (isotropic rotation: ⅔ of it is ⟂ r).
        * ``rate_disturbance_rms_rad_s`` — gyro truth minus schedule rate:
          √(ω_tr² + tilt² · mean|ω_sched|²).
        """
        t = np.arange(0.0, schedule.duration_s, 1.0 / rate_hz)
        kin = schedule.kinematics(t)
        r_b = -np.asarray(self.pivot_offset_m, dtype=float)
        w = kin.omega_body_rad_s
        a_pivot = cross3(kin.omega_dot_body_rad_s2, r_b) + cross3(w, cross3(w, r_b))
        # translations of the schedule itself are commanded motion, also non-gravity
        a_pivot = a_pivot + quat_rotate(
            np.stack([kin.quat_nb[:, 0], -kin.quat_nb[:, 1], -kin.quat_nb[:, 2], -kin.quat_nb[:, 3]], -1),
            kin.acceleration_m_s2,
        )
        pivot_ms = float(np.mean(np.sum(a_pivot**2, axis=1)))
        fc = 0.5 * sum(self.tremor_band_hz)
        tremor_rot_acc_ms = (2 * math.pi * fc) ** 2 * self.tremor_rate_rms_rad_s**2 * float(r_b @ r_b) * 2 / 3
        acc = math.sqrt(self.tremor_acc_rms_m_s2**2 + self.sway_acc_rms_m_s2**2 + pivot_ms + tremor_rot_acc_ms)
        tilt = math.radians(self.axis_wobble_rms_deg)
        rate = math.sqrt(self.tremor_rate_rms_rad_s**2 + tilt**2 * float(np.mean(np.sum(w**2, axis=1))))
        return {
            "external_acc_rms_m_s2": acc,
            "rate_disturbance_rms_rad_s": rate,
            "pivot_acc_rms_m_s2": math.sqrt(pivot_ms),
        }


def hand_preset_names() -> list[str]:
    """Names of the hand presets shipped in ``gyrosim/presets/hands/*.toml``."""
    return builtin_names("presets", "hands")


# each imperfection of the module docstring and the fields that carry its size (switching it off zeroes them)
IMPERFECTIONS: dict[str, tuple[str, ...]] = {
    "tremor": ("tremor_acc_rms_m_s2",),
    "tremor_rotation": ("tremor_rate_rms_rad_s",),
    "sway": ("sway_acc_rms_m_s2",),
    "pivot": ("pivot_offset_m",),
    "wobble": ("axis_wobble_rms_deg",),
}

_HAND_KEYS = {f for f in Hand.__dataclass_fields__}


def hand_from_dict(data: dict[str, Any], default_name: str = "custom") -> Hand:
    """Build a :class:`Hand` from a preset table, rejecting unknown keys by name."""
    unknown = set(data) - _HAND_KEYS
    if unknown:
        raise PresetError(f"unknown hand key(s) {sorted(unknown)}; allowed: {sorted(_HAND_KEYS)}")
    kw = dict(data)
    kw.setdefault("name", default_name)
    for key in ("tremor_band_hz", "sway_band_hz", "wobble_band_hz", "pivot_offset_m"):
        if key in kw:
            kw[key] = tuple(float(x) for x in kw[key])
    return Hand(**kw)


def load_hand(name_or_path: str | Path) -> Hand:
    """Load a hand preset by name (``ideal``, ``steady``, ``typical``, ``shaky``) or TOML path."""
    name, data = load_named_toml(("presets", "hands"), name_or_path, "hand preset", PresetError)
    return hand_from_dict(data, default_name=name)
