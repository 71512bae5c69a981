"""Magnetometer candidates of the loop: what each one is, how big it can plausibly be, and what it needs.

The magnetometer model the loop fits (Ozyagcilar, Freescale AN4246 eq. 8, with the axes rotation of
:class:`gyrosim.effects.FrameRotation`):

    m_k = A R(θ)ᵀ C_k B_n + h + ε_k        (attitude reference: C_k body←ENU from the reference)
    |A⁻¹ (m_k − h)| = F + ε_k               (no attitude reference: the field magnitude only)

B_n (µT, ENU) or F (µT) is the reference field, always fitted (the site's field is not assumed).
The candidates:

| kind | parameters | what it needs |
|---|---|---|
| ``hard_iron`` | h (3, µT) | the board turning (else h is one more constant field, part of B_n) |
| ``soft_iron`` | the trace-free symmetric part of A − I (5) | attitude coverage along all three body axes |
| ``frame_rotation`` | θ (3, rad), the magnetometer-to-IMU misalignment | an attitude reference (|m| does not see it) |

Soft iron is induced magnetisation, a symmetric tensor (AN4246 §4); its trace (a common scale of
the three axes) is the gauge that the free field magnitude absorbs (A → (1 + s) A, B_n → B_n / (1 + s)
leave every m_k unchanged), so the loop fits the five trace-free components and reports A scaled to
trace 3 — the first-order form of the "unit determinant" normalisation of :mod:`calib.mag`.  The
antisymmetric part of a general 3×3 A is a small rotation: it is ``frame_rotation`` (a separate
candidate, so a general 9-parameter A = symmetric 6 (5 + gauge) + rotation 3 is covered by the two).

Plausible sizes (the identifiability gate's ρ, and the bound beyond which a fit is refused as a
proxy): the largest a datasheet or the ``phone`` preset allows at 3σ — hard iron 450 µT (phone
150 µT 1σ; AK8963 zero-field offset ±300 µT), soft iron 0.25 per component (phone 8 % 1σ),
misalignment 5° per axis (phone 1° 1σ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from gyrosim import effects as E

__all__ = ["MagTerm", "MAG_TERMS", "mag_term", "soft_iron_matrix", "soft_iron_params_of", "is_mag_kind"]

# trace-free symmetric basis: S = Σ_j s_j E_j
_E = np.zeros((5, 3, 3))
_E[0][0, 0], _E[0][2, 2] = 1.0, -1.0          # S_xx (S_zz = −S_xx − S_yy)
_E[1][1, 1], _E[1][2, 2] = 1.0, -1.0          # S_yy
_E[2][0, 1] = _E[2][1, 0] = 1.0               # S_xy
_E[3][0, 2] = _E[3][2, 0] = 1.0               # S_xz
_E[4][1, 2] = _E[4][2, 1] = 1.0               # S_yz
SOFT_BASIS = _E


def soft_iron_matrix(s: np.ndarray) -> np.ndarray:
    """A = I + Σ_j s_j E_j (trace 3)."""
    return np.eye(3) + np.tensordot(np.asarray(s, float), _E, axes=1)


def soft_iron_params_of(a: np.ndarray) -> np.ndarray:
    """The five trace-free components of a 3×3 soft-iron matrix as the loop can see it: the
    symmetric part scaled to trace 3 (the gauge), minus I."""
    a = np.asarray(a, float)
    p = 0.5 * (a + a.T)
    p = p * 3.0 / np.trace(p) - np.eye(3)
    return np.array([p[0, 0], p[1, 1], p[0, 1], p[0, 2], p[1, 2]])


@dataclass(frozen=True)
class MagTerm:
    """One magnetometer candidate kind (see the module docstring)."""

    kind: str
    param_names: tuple[str, ...]
    plausible_max: float                 # ρ per parameter (its units)
    driver: str
    separated_by: str
    needs_attitude: bool
    display: tuple[float, str]           # report factor and unit
    to_effect: Callable[[np.ndarray], E.Effect]
    truth_params: Callable[[E.Effect], np.ndarray]    # what the loop can identify of a true effect
    # what the field magnitude alone cannot separate from |B| without field-direction coverage, in
    # words ("": the term does not need direction coverage)
    coverage_part: str = ""

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def summary(self, values: np.ndarray, sigmas: np.ndarray) -> str:
        f, unit = self.display
        vals = ", ".join(f"{n} {v * f:.3g}±{s * f:.2g}" for n, v, s in zip(self.param_names, values, sigmas))
        return f"{self.kind} [{vals}] {unit}"


MAG_TERMS: dict[str, MagTerm] = {
    t.kind: t
    for t in (
        MagTerm(
            "hard_iron",
            ("h_x", "h_y", "h_z"),
            450.0,
            "a field fixed in the body frame (magnetised parts, the sensor's zero-field offset)",
            "rotations of the board (a constant field in the body frame turns against the Earth's)",
            False,
            E.HardIron.display_unit("magnetometer"),
            lambda th: E.HardIron(value=np.asarray(th, float)),
            lambda e: np.asarray(e.value, float),
            "the hard iron along the turning axis (calib mag's circle fit gives the other two components)",
        ),
        MagTerm(
            "soft_iron",
            ("S_xx", "S_yy", "S_xy", "S_xz", "S_yz"),
            0.25,
            "the field induced in the board's ferrous parts, proportional to the applied field",
            "attitudes that point the field along and against all three body axes",
            False,
            (1.0, "(A − I, trace-free)"),
            lambda th: E.SoftIron(matrix=soft_iron_matrix(th)),
            lambda e: soft_iron_params_of(e.matrix),
            "the soft iron",
        ),
        MagTerm(
            "frame_rotation",
            ("theta_x", "theta_y", "theta_z"),
            math.radians(5.0),
            "the magnetometer's axes rotated against the IMU frame (the reference attitude's frame)",
            "an attitude reference in the IMU's own frame (truth); against an optical body frame a rotation of "
            "that frame to the IMU looks the same — the gyro residual against the same reference separates them",
            True,
            E.FrameRotation.display_unit("magnetometer"),
            lambda th: E.FrameRotation(angles=np.asarray(th, float)),
            lambda e: np.asarray(e.angles, float),
        ),
    )
}


def is_mag_kind(kind: str) -> bool:
    """Whether ``kind`` is one of the magnetometer terms the loop knows (:data:`MAG_TERMS`)."""
    return kind in MAG_TERMS


def mag_term(kind: str) -> MagTerm:
    """The :class:`MagTerm` of ``kind``; raises KeyError naming the known kinds."""
    try:
        return MAG_TERMS[kind]
    except KeyError:
        raise KeyError(f"{kind!r} is no magnetometer candidate; known: {', '.join(MAG_TERMS)}") from None
