"""The prior a session is judged against, and which parameters THIS recording determines.

The parameters are the linear model's, both triads, in :meth:`gyrosim.calibration.Calibration.vector` order
(θ, 18 values): gyro bias b (rad/s), scale factor S, non-orthogonality G (dimensionless), then the
accelerometer's bias b_a (m/s²), S_a, G_a; body frame Right-Forward-Up.

**The prior** (:class:`Prior`) is what the user has without this session:

* by default a *maker-calibrated* sensor: S = G = 0 and b_a = S_a = G_a = 0, each with a datasheet-class
  tolerance as its 1σ — gyro S 1 %, G 1 %; accelerometer b_a 0.25 m/s², S_a 1 %, G_a 1 % (the InvenSense
  MPU-9250 specification's initial tolerances, ±3 % sensitivity, ±2 % cross-axis, ±60–80 mg zero-g, read as
  3σ and rounded up; a maker-calibrated part is inside them).  ``calib run --prior-tolerance`` sets them;
* or a *previous calibration* (``calib run --prior cal.json``): the values it applied and their σ, so that
  calibrations accumulate over sessions.

The gyro bias has no prior (σ = ∞): it changes from one power-on to the next, so each session measures it at
its own rest.

**Determined** (:func:`determine`): a parameter is determined by this recording when its posterior σ is at most
``ratio`` (½) of the prior's — the data then carry at least 1/ratio² − 1 = 3 times the prior's information about
it; what decides is whether the data moved its *distribution* away from the prior, not whether the value moved:
a sensor whose S the session pins at the maker's 0 ± 0.0001 is determined too (a test of the value's shift would
call the best sensors' parameters undetermined and, with S and G drawn around zero, leave some at the prior by
chance — on gyrosim's MPU-9250 a G within 3σ of zero in about one session in five).  The caller adds what the
numbers cannot show (:class:`Gate`): a motion that breaks the estimator's model, a diverged estimate, an
accelerometer the session took as calibrated — each undetermines the parameters it concerns, with its reason.

A determined parameter's value is the session's estimate combined with the prior (inverse-variance weights,
per parameter: the prior's information is at most a third of the data's, so the shift is ≤ 25 % of the way back
and for the sessions calib is built for ~10⁻⁴ of it); an undetermined one stays at the prior.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrosim.calibration import Calibration
from gyrosim.effects import nonortho_matrix

__all__ = ["PARAMETERS", "Prior", "Gate", "Determination", "determine", "compose", "combine", "DETERMINED_RATIO",
           "MAKER_TOLERANCE", "MISALIGNMENT_PRIOR_RAD"]

# (triad, kind, JSON key) in θ order, three values each
PARAMETERS = (("gyro", "bias", "bias_rad_s"), ("gyro", "scale_factor", "scale_factor"),
              ("gyro", "nonorthogonality", "nonorthogonality"), ("accelerometer", "bias", "bias_m_s2"),
              ("accelerometer", "scale_factor", "scale_factor"), ("accelerometer", "nonorthogonality",
                                                                  "nonorthogonality"))
# datasheet-class 1σ of a maker-calibrated sensor (module docstring): name → tolerance
MAKER_TOLERANCE = {"gyro_scale": 0.01, "gyro_nonorth": 0.01, "acc_bias_m_s2": 0.25, "acc_scale": 0.01,
                   "acc_nonorth": 0.01}
# the gyro triad's rotation against the accelerometer's (rad, 1σ per axis) on a part no one has measured: an
# assembly's rotation between two dies or chips, 1° typical, 2° taken as 1σ (datasheets do not state it)
MISALIGNMENT_PRIOR_RAD = 0.035
DETERMINED_RATIO = 0.5   # σ_posterior ≤ ratio · σ_prior: the data carry ≥ 3× the prior's information
GYRO = slice(0, 9)
ACC = slice(9, 18)
SG = slice(3, 9)


def _block(theta: np.ndarray) -> dict:
    """θ (18,) → {"gyro": {key: [3]}, "accelerometer": {key: [3]}} with the JSON keys of :data:`PARAMETERS`; a
    value that is not a finite number (no prior: σ = ∞) is written as null on purpose."""
    out: dict = {"gyro": {}, "accelerometer": {}}
    for i, (triad, _, key) in enumerate(PARAMETERS):
        vals = [v.item() if hasattr(v, "item") else v for v in theta[3 * i:3 * i + 3]]
        out[triad][key] = [None if isinstance(v, float) and not math.isfinite(v) else v for v in vals]
    return out


def _unblock(d: dict, dtype=float) -> np.ndarray:
    return np.array([v for triad, _, key in PARAMETERS for v in d[triad][key]], dtype=dtype)


@dataclass(frozen=True)
class Prior:
    """Mean and 1σ (18,) of every parameter before this session (module docstring); ``source`` says where
    they come from, in words (``maker-calibrated sensor, datasheet tolerance`` or the previous file);
    ``previous``: a previous calibration, whose values the session's recording is compensated with first."""

    mean: np.ndarray
    sigma: np.ndarray
    source: str = "maker-calibrated sensor, datasheet tolerance"
    previous: bool = False

    def __post_init__(self) -> None:
        for name in ("mean", "sigma"):
            a = np.array(getattr(self, name), float).reshape(18)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if np.any(~(self.sigma > 0)):
            raise ValueError("every prior σ must be positive (∞ for no prior)")

    @classmethod
    def maker(cls, gyro_scale: float = MAKER_TOLERANCE["gyro_scale"],
              gyro_nonorth: float = MAKER_TOLERANCE["gyro_nonorth"],
              acc_bias_m_s2: float = MAKER_TOLERANCE["acc_bias_m_s2"], acc_scale: float = MAKER_TOLERANCE["acc_scale"],
              acc_nonorth: float = MAKER_TOLERANCE["acc_nonorth"]) -> "Prior":
        """A maker-calibrated sensor: every parameter 0 ± its tolerance (1σ); the gyro bias without a prior."""
        sigma = np.repeat([math.inf, gyro_scale, gyro_nonorth, acc_bias_m_s2, acc_scale, acc_nonorth], 3)
        return cls(np.zeros(18), sigma)

    def with_accelerometer(self, theta: np.ndarray, sigma: np.ndarray, source: str) -> "Prior":
        """The prior with the accelerometer's b_a, S_a, G_a (``theta`` (9,), 1σ ``sigma``) measured by something
        other than this session (a protocol's box-face poses): the recording is read through them first
        (``previous``), as a previous calibration's."""
        mean, sig = self.mean.copy(), self.sigma.copy()
        mean[ACC], sig[ACC] = theta, np.maximum(np.asarray(sigma, float), 1e-12)
        return Prior(mean, sig, f"{source}; the gyro: {self.source}", True)

    @classmethod
    def from_tolerance(cls, text: str) -> "Prior":
        """``calib run --prior-tolerance``: ``S=0.02,G=0.01,acc_bias=0.3,acc_S=0.02,acc_G=0.01`` (any subset; the
        rest keep :data:`MAKER_TOLERANCE`), or one number for every dimensionless one (S, G, acc_S, acc_G)."""
        names = {"s": "gyro_scale", "g": "gyro_nonorth", "acc_bias": "acc_bias_m_s2", "acc_s": "acc_scale",
                 "acc_g": "acc_nonorth"}
        values = dict(MAKER_TOLERANCE)
        text = text.strip()
        try:
            if "=" not in text:
                v = float(text)
                values.update({k: v for k in ("gyro_scale", "gyro_nonorth", "acc_scale", "acc_nonorth")})
            else:
                for item in text.split(","):
                    key, _, val = item.partition("=")
                    key = key.strip().lower()
                    if key not in names:
                        raise ValueError(f"unknown name {key!r}")
                    values[names[key]] = float(val)
        except ValueError as exc:
            raise ValueError(f"prior tolerance {text!r}: {exc}; write e.g. S=0.02,G=0.01,acc_bias=0.3,acc_S=0.02,"
                             "acc_G=0.01 (1σ; acc_bias in m/s²) or one number for S, G, acc_S, acc_G") from None
        if not all(math.isfinite(v) and v > 0 for v in values.values()):
            raise ValueError(f"prior tolerance {text!r}: every tolerance must be a positive number")
        return cls.maker(**values)

    @classmethod
    def from_calibration(cls, cal: Calibration, source: str, fallback: "Prior | None" = None) -> "Prior":
        """A previous calibration as the prior: what it applied (its ``applied`` block, or every estimated value
        of a file written before there was one) with its σ; a parameter it left at its own prior keeps that
        prior's σ (``fallback``, default :meth:`maker`), an accelerometer it did not estimate too."""
        fallback = fallback or cls.maker()
        if cal.applied is not None:
            mean = cal.applied.vector()
            sigma = cal.applied.sigma_vector()
        else:
            mean = np.concatenate([cal.vector("gyro"), cal.vector("accelerometer")])
            sigma = np.concatenate([np.sqrt(np.diag(cal.linear_covariance("gyro"))),
                                    np.sqrt(np.diag(cal.linear_covariance("accelerometer")))])
            if not cal.has("accelerometer", "bias"):
                sigma[ACC] = np.nan
        sigma = np.where(np.isfinite(sigma) & (sigma > 0), sigma, fallback.sigma)
        mean = np.where(np.isfinite(mean), mean, 0.0)
        mean[0:3], sigma[0:3] = 0.0, math.inf     # the bias: every session measures its own
        return cls(mean, sigma, source, previous=True)

    def to_dict(self) -> dict:
        return {"source": self.source, "previous_calibration": self.previous, "mean": _block(self.mean),
                "sigma": _block(self.sigma)}


@dataclass(frozen=True)
class Gate:
    """A finding that undetermines parameters whatever their σ: ``mask`` (18,) bool of those it concerns and
    the ``reason`` in words (what was found and what it does to them)."""

    mask: np.ndarray
    reason: str


@dataclass(frozen=True)
class Determination:
    """Per parameter (18,): ``determined`` and, when not, ``reasons`` ('' when determined); ``ratio`` = σ / σ_prior."""

    determined: np.ndarray
    reasons: tuple[str, ...]
    ratio: np.ndarray
    rule: float = DETERMINED_RATIO
    notes: tuple[str, ...] = field(default=())

    def names(self, mask: np.ndarray | None = None) -> list[str]:
        """Short names (S_x, G_y, acc b_z, …) of the parameters in ``mask`` (default: the determined ones)."""
        m = self.determined if mask is None else mask
        short = {"bias": "b", "scale_factor": "S", "nonorthogonality": "G"}
        out = []
        for i, (triad, kind, _) in enumerate(PARAMETERS):
            for j, ax in enumerate("xyz"):
                if m[3 * i + j]:
                    out.append(("acc " if triad == "accelerometer" else "") + f"{short[kind]}_{ax}")
        return out

    def grouped(self, mask: np.ndarray, gyro_also: tuple[str, ...] = ()) -> str:
        """The parameters in ``mask`` for a terminal line, grouped: "S, G_y; accelerometer b, S" (a kind whose
        three axes are all in it by its letter alone), '' for none; ``gyro_also``: further names in the gyro's
        group (a term beyond the 18, e.g. its rotation against the accelerometer)."""
        short = {"bias": "b", "scale_factor": "S", "nonorthogonality": "G"}
        parts: dict[str, list[str]] = {"gyro": [], "accelerometer": []}
        for i, (triad, kind, _) in enumerate(PARAMETERS):
            m = np.asarray(mask, bool)[3 * i:3 * i + 3]
            if m.all():
                parts[triad].append(short[kind])
            else:
                parts[triad] += [f"{short[kind]}_{ax}" for ax, on in zip("xyz", m) if on]
        text = ", ".join(parts["gyro"]).replace("b, ", "bias, ") if parts["gyro"] else ""
        if text == "b":
            text = "bias"
        text = ", ".join(t for t in (text, *gyro_also) if t)
        acc = ", ".join(parts["accelerometer"])
        return "; ".join(t for t in (text, f"accelerometer {acc}" if acc else "") if t)

    def to_dict(self) -> dict:
        return {"rule": f"posterior σ ≤ {self.rule:g} × prior σ (the data carry ≥ {1 / self.rule**2 - 1:g}× the "
                        "prior's information), unless a finding below undetermines it",
                "determined": _block(self.determined.astype(bool)),
                "sigma_ratio": _block(self.ratio),
                "reasons": sorted(set(r for r in self.reasons if r))}


def determine(estimate: np.ndarray, sigma: np.ndarray, prior: Prior, gates: tuple[Gate, ...] = (),
              ratio: float = DETERMINED_RATIO) -> Determination:
    """Which of the 18 parameters this recording determines (module docstring): σ ≤ ``ratio`` σ_prior, finite
    estimate, and no gate against it.  The gyro bias (no prior) is determined when its σ is finite."""
    sigma = np.asarray(sigma, float)
    est = np.asarray(estimate, float)
    r = np.where(np.isfinite(prior.sigma), sigma / prior.sigma, 0.0)
    ok = np.isfinite(sigma) & np.isfinite(est) & (r <= ratio)
    reasons = ["" if ok[i] else ("not estimated" if not np.isfinite(est[i]) or not np.isfinite(sigma[i]) else
                                 f"σ {r[i]:.2f} of the prior's (determined at ≤ {ratio:g})") for i in range(18)]
    for gate in gates:   # a finding outranks the numbers: its reason is the one given
        for i in np.flatnonzero(np.asarray(gate.mask, bool)):
            reasons[i] = gate.reason
            ok[i] = False
    return Determination(ok, tuple(reasons), r, ratio)


def combine(estimate: np.ndarray, sigma: np.ndarray, prior_mean: np.ndarray, prior_sigma: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Inverse-variance combination of the session's estimate with the prior, per parameter (∞ prior σ: the
    estimate itself): (value, σ)."""
    w_e = 1.0 / np.maximum(np.asarray(sigma, float), 1e-300) ** 2
    w_p = np.where(np.isfinite(prior_sigma), 1.0 / np.asarray(prior_sigma, float) ** 2, 0.0)
    value = (w_e * estimate + w_p * prior_mean) / (w_e + w_p)
    return value, 1.0 / np.sqrt(w_e + w_p)


def _m(s: np.ndarray, g: np.ndarray) -> np.ndarray:
    return np.eye(3) + np.diag(s) + nonortho_matrix(g)


def compose(outer: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """The one linear model (9,) [b, S, G] of a triad read through ``inner`` then ``outer``:
    x̃ = M_o (M_i x + b_i) + b_o, so M = M_o M_i (its symmetric part's diagonal − 1 and off-diagonal: S, G; the
    antisymmetric part, a rotation of the triad, is not in the model and is dropped) and b = M_o b_i + b_o.  For a
    previous calibration (outer) and what this session finds on the recording it compensated (inner)."""
    mo, mi = _m(outer[3:6], outer[6:9]), _m(inner[3:6], inner[6:9])
    m = mo @ mi
    sym = 0.5 * (m + m.T)
    b = mo @ inner[0:3] + outer[0:3]
    return np.concatenate([b, np.diag(sym) - 1.0, [sym[1, 2], sym[0, 2], sym[0, 1]]])
