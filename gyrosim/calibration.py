"""One calibration result for every estimator: effects of the vocabulary, their covariance, a verdict.

A :class:`Calibration` is what any estimator returns (``calib``'s filters, a user's estimator, the
simulator's own truth as an oracle):

* ``gyro`` / ``accelerometer``: the estimated effects, as objects of the shared vocabulary
  (:mod:`gyrosim.effects`: ``bias``, ``scale_factor``, ``nonorthogonality``, ..., and the noise
  processes ``white_noise`` / ``random_walk`` when the estimator measured them).  The measurement
  model is the vocabulary's (Zhou 2020 eq. 1 for the first three):

      ω̃ = (I + diag(S_g) + N(G_g)) ω + b_g + ε          f̃ = (I + diag(S_a) + N(G_a)) f + b_a + v

  body frame Right-Forward-Up, SI units (rad/s, m/s², dimensionless S and G);
* ``covariance``: (P, P) over :meth:`Calibration.parameter_names` — every parameter of every
  deterministic effect, gyro first, in the order of the effects and of ``Effect.param_names``
  (NaN where the estimator gives no uncertainty);
* ``status``: ``ok``, ``diverged`` (the estimate ran away: do not use it) or ``inconsistent``
  (the estimate failed its own consistency check: σ does not describe its error), and
  ``warnings``: named findings, each saying what to do;
* ``diagnostics``: JSON-able extras of the estimator (rest segments, noise levels, NIS, ...),
  written at the top level of the JSON; ``history``: the estimator's run history for viewers
  (not serialised);
* ``report``: what a session run adds around the estimate (``calib run``, :func:`calib.session.run.run_session`):
  sections named in :data:`REPORT_SECTIONS` — ``input`` (what the input boundary read and did), ``coaching``
  (what the hand cost), ``truth`` (a simulated file's own device) — written at the top level of the JSON
  after the estimate, under those keys, and read back into ``report`` by :meth:`Calibration.from_dict`;
* ``applied`` (:class:`Applied`, optional): what :meth:`Calibration.compensate` applies when it is not every
  estimated value — the parameters this session determined, and the prior's values for the rest (a
  maker-calibrated sensor's zeros, or a previous calibration's values); a file without it applies every
  estimated value, as before.

It saves and loads itself (:meth:`to_json` / :meth:`from_json`, versioned, UTF-8, NaN never written:
``null`` with the reason in ``warnings``) and compensates a recording (:meth:`compensate`, which
inverts the effects with :meth:`gyrosim.sensor_model.SensorModel.compensate_triad`).  Exports to
other tools live in :mod:`gyrosim.exchange` (Kalibr ``imu.yaml``, imucal JSON).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .effects import (
    Bias,
    Effect,
    GyroAccMisalignment,
    NonOrthogonality,
    ScaleFactor,
    SignalContext,
    effect_from_dict,
)
from .errors import GyrosimError
from .recording import FRAMES, Recording

__all__ = ["Calibration", "Applied", "CALIBRATION_FORMAT", "CALIBRATION_VERSION", "STATUSES", "REPORT_SECTIONS",
           "truth_calibration"]

CALIBRATION_FORMAT = "gyrosim.calibration"
CALIBRATION_VERSION = 1
STATUSES = ("ok", "diverged", "inconsistent")
TRIADS = ("gyro", "accelerometer")
# the sections a session run adds around the estimate (``calib run --json`` promises these keys): the input
# boundary's report, the coaching, a simulated file's truth, and what decided the applied parameters (the motion,
# the prior, the held-out check)
REPORT_SECTIONS = ("coaching", "input", "truth", "motion", "prior", "held_out_check")
# the summary blocks of the JSON (``calib run --json`` promises these keys): kind → key per triad
_SUMMARY = {"gyro": ((Bias.kind, "bias_rad_s"), (ScaleFactor.kind, "scale_factor"),
                     (NonOrthogonality.kind, "nonorthogonality")),
            "accelerometer": ((Bias.kind, "bias_m_s2"), (ScaleFactor.kind, "scale_factor"),
                              (NonOrthogonality.kind, "nonorthogonality"))}
# further summary keys, written only when the calibration has the effect: the gyro triad's rotation against the
# accelerometer's (rad about x, y, z; gyrosim.effects.GyroAccMisalignment)
_EXTRA_SUMMARY = {"gyro": {GyroAccMisalignment.kind: "misalignment_rad"}}
# the linear model ω̃ = (I + S + N) ω + b (Zhou 2020 eq. 1): its effect classes, by kind
_LINEAR = {cls.kind: cls for cls in (Bias, ScaleFactor, NonOrthogonality)}
LINEAR_KINDS = tuple(_LINEAR)  # ("bias", "scale_factor", "nonorthogonality"), the vector order


def _deterministic(effects: tuple[Effect, ...]) -> tuple[Effect, ...]:
    return tuple(e for e in effects if not e.stochastic)


def _clean(x: Any, path: str, nan_paths: list[str]) -> Any:
    """JSON-able copy of ``x`` with every non-finite float replaced by None (paths collected)."""
    if isinstance(x, Mapping):
        return {str(k): _clean(v, f"{path}.{k}" if path else str(k), nan_paths) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v, f"{path}[{i}]", nan_paths) for i, v in enumerate(x)]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist(), path, nan_paths)
    if isinstance(x, (np.floating, float)):
        v = float(x)
        if not math.isfinite(v):
            nan_paths.append(path)
            return None
        return v
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _triad_blocks(v: np.ndarray) -> dict[str, dict[str, Any]]:
    """(18,) in :meth:`Calibration.vector` order, gyro then accelerometer → {triad: {JSON key: [3]}}."""
    out: dict[str, dict[str, Any]] = {}
    for i, triad in enumerate(TRIADS):
        out[triad] = {key: v[9 * i + 3 * j:9 * i + 3 * j + 3].tolist() for j, (_, key) in enumerate(_SUMMARY[triad])}
    return out


@dataclass(frozen=True, eq=False)
class Applied:
    """What :meth:`Calibration.compensate` applies, both triads, the linear model's 18 values in
    :meth:`Calibration.vector` order (gyro b rad/s, S, G; accelerometer b m/s², S, G): ``values`` and their 1σ
    ``sigma``; ``from_session`` True where the value is this session's (determined and not rejected by its
    held-out check), False where it is the prior's; ``determined`` True where the session determined it (a
    held-out check may still have kept it from being applied); ``prior``: where the other values come from, in
    words; ``summary``: one line for the person at the terminal; ``notes``: why (one line each: the motion, the
    held-out check, what was not determined and what would determine it).  ``gyro_misalignment_rad`` (3,) and its
    ``gyro_misalignment_std_rad``: the gyro triad's rotation against the accelerometer's
    (:class:`~gyrosim.effects.GyroAccMisalignment`, rad about body x, y, z) when this session determined it and its
    held-out check let S, G be applied; None otherwise (not applied: the maker's 0)."""

    values: np.ndarray
    sigma: np.ndarray
    from_session: np.ndarray
    determined: np.ndarray
    prior: str = ""
    summary: str = ""
    notes: tuple[str, ...] = ()
    gyro_misalignment_rad: np.ndarray | None = None
    gyro_misalignment_std_rad: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name, dtype in (("values", float), ("sigma", float), ("from_session", bool), ("determined", bool)):
            a = np.array(getattr(self, name), dtype=dtype).reshape(18)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "notes", tuple(self.notes))
        for name in ("gyro_misalignment_rad", "gyro_misalignment_std_rad"):
            if getattr(self, name) is not None:
                a = np.array(getattr(self, name), dtype=float).reshape(3)
                a.setflags(write=False)
                object.__setattr__(self, name, a)

    def vector(self) -> np.ndarray:
        return np.array(self.values)

    def sigma_vector(self) -> np.ndarray:
        return np.array(self.sigma)

    def value(self, triad: str, kind: str) -> np.ndarray:
        i = TRIADS.index(triad) * 9 + LINEAR_KINDS.index(kind) * 3
        return np.array(self.values[i:i + 3])

    def effects(self, triad: str) -> tuple[Effect, ...]:
        """The applied model of ``triad`` as vocabulary effects (what compensation inverts): the linear model, and
        for the gyro its rotation against the accelerometer when applied."""
        linear = tuple(_LINEAR[kind](value=self.value(triad, kind)) for kind in LINEAR_KINDS)
        if triad == "gyro" and self.gyro_misalignment_rad is not None:
            return linear + (GyroAccMisalignment(value=self.gyro_misalignment_rad),)
        return linear

    def to_dict(self) -> dict[str, Any]:
        """``applied`` in the JSON: per triad the values under the summary blocks' keys, ``std`` and
        ``from_session`` (both the same keys), then ``prior`` and ``summary``."""
        values = _triad_blocks(self.values)
        sigma = _triad_blocks(np.where(np.isfinite(self.sigma), self.sigma, None))  # ∞ (no prior): null
        session = _triad_blocks(self.from_session)
        out: dict[str, Any] = {}
        for triad in TRIADS:
            out[triad] = {**values[triad], "std": sigma[triad], "from_session": session[triad]}
        if self.gyro_misalignment_rad is not None:   # the rotation, when applied: always this session's
            key = _EXTRA_SUMMARY["gyro"][GyroAccMisalignment.kind]
            std = self.gyro_misalignment_std_rad
            out["gyro"][key] = self.gyro_misalignment_rad.tolist()
            out["gyro"]["std"][key] = [None] * 3 if std is None else std.tolist()
            out["gyro"]["from_session"][key] = [True] * 3
        out["prior"] = self.prior
        out["summary"] = self.summary
        out["notes"] = list(self.notes)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], determined: np.ndarray | None = None) -> "Applied":
        def flat(key: str | None, default: float) -> np.ndarray:
            vals = []
            for triad in TRIADS:
                block = d.get(triad) or {}
                block = block if key is None else (block.get(key) or {})
                for _, k in _SUMMARY[triad]:
                    vals += [default if v is None else v for v in (block.get(k) or [default] * 3)]
            return np.array(vals, float)

        session = flat("from_session", 0.0).astype(bool)
        gyro = d.get("gyro") or {}
        key = _EXTRA_SUMMARY["gyro"][GyroAccMisalignment.kind]
        alpha = gyro.get(key)
        alpha_std = (gyro.get("std") or {}).get(key)
        alpha_std = None if alpha_std is None or any(v is None for v in alpha_std) else alpha_std
        return cls(flat(None, 0.0), flat("std", np.nan), session, session if determined is None else determined,
                   d.get("prior", ""), d.get("summary", ""), tuple(d.get("notes") or ()), alpha, alpha_std)


@dataclass(frozen=True)
class Calibration:
    """A calibration of an IMU: estimated vocabulary effects with covariance, status and warnings."""

    gyro: tuple[Effect, ...] = ()
    accelerometer: tuple[Effect, ...] = ()
    covariance: np.ndarray | None = None
    status: str = "ok"
    warnings: tuple[str, ...] = ()
    method: str = ""
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    history: Any = field(default=None, repr=False, compare=False)
    report: Mapping[str, Any] = field(default_factory=dict)
    applied: Applied | None = None

    def __post_init__(self) -> None:
        for triad in TRIADS:
            effs = tuple(getattr(self, triad))
            for e in effs:
                if not isinstance(e, Effect):
                    raise GyrosimError(f"Calibration.{triad} must hold vocabulary effects, got {type(e).__name__}")
                if triad not in e.triads:
                    raise GyrosimError(f"effect {e.kind!r} does not apply to the {triad}")
            object.__setattr__(self, triad, effs)
        if self.status not in STATUSES:
            raise GyrosimError(f"Calibration.status must be one of {STATUSES}, got {self.status!r}")
        n = len(self.parameter_names())
        cov = np.full((n, n), np.nan) if self.covariance is None else np.array(self.covariance, dtype=float)
        if cov.shape != (n, n):
            raise GyrosimError(f"Calibration.covariance must be {n}×{n} over {self.parameter_names()}, got {cov.shape}")
        cov.setflags(write=False)
        object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "diagnostics", dict(self.diagnostics))
        report = dict(self.report)
        unknown = [k for k in report if k not in REPORT_SECTIONS]
        if unknown:
            raise GyrosimError(f"Calibration.report takes the sections {REPORT_SECTIONS}, got {unknown}")
        clash = [k for k in report if k in self.diagnostics]
        if clash:
            raise GyrosimError(f"Calibration.report and .diagnostics both hold {clash}: one key, one place in the JSON")
        object.__setattr__(self, "report", report)
        missing = [name for name, v in zip(self.parameter_names(), np.diag(cov)) if not np.isfinite(v)]
        warnings = tuple(self.warnings)
        if missing:
            note = (f"no uncertainty for {len(missing)} parameter(s) ({', '.join(missing[:4])}"
                    f"{', …' if len(missing) > 4 else ''}): the estimator gave none; their std is null in the JSON")
            if not any(w.startswith("no uncertainty for") for w in warnings):
                warnings = warnings + (note,)
        object.__setattr__(self, "warnings", warnings)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_linear(cls, *, gyro: Mapping[str, np.ndarray] | None = None,
                    accelerometer: Mapping[str, np.ndarray] | None = None, covariance: np.ndarray | None = None,
                    **kwargs: Any) -> "Calibration":
        """From the linear model's arrays, e.g. ``gyro={"bias": b, "scale_factor": S, "nonorthogonality": G}``
        (kinds of the vocabulary, each (3,) in SI); ``covariance`` over the parameters in that order."""
        def build(d: Mapping[str, np.ndarray] | None) -> tuple[Effect, ...]:
            out = []
            for kind, value in (d or {}).items():
                if kind not in _LINEAR:
                    raise GyrosimError(f"from_linear takes {tuple(_LINEAR)}, got {kind!r}")
                out.append(_LINEAR[kind](value=value))
            return tuple(out)

        return cls(gyro=build(gyro), accelerometer=build(accelerometer), covariance=covariance, **kwargs)

    def as_applied(self) -> "Calibration":
        """The calibration as :meth:`compensate` applies it, for exports: with an :attr:`applied` block, its effects
        (the values the session determined, the prior's for the rest; the gyro's rotation when applied) with this
        calibration's noise terms, σ from the block (no cross-covariance); without one, this calibration itself.
        Another tool given the export then applies what ``calib apply`` would."""
        a = self.applied
        if a is None:
            return self
        gyro = a.effects("gyro") + tuple(e for e in self.gyro if e.stochastic)
        acc = a.effects("accelerometer") + tuple(e for e in self.accelerometer if e.stochastic)
        alpha_std = a.gyro_misalignment_std_rad if a.gyro_misalignment_std_rad is not None else np.full(3, np.nan)
        sigma = [a.sigma[:9]] + ([alpha_std] if a.gyro_misalignment_rad is not None else [])
        sigma = np.concatenate(sigma + [a.sigma[9:]])
        return replace(self, gyro=gyro, accelerometer=acc, covariance=np.diag(sigma**2), applied=None)

    # ------------------------------------------------------------------ parameters
    def parameter_names(self) -> list[str]:
        """``triad.kind.field[i]`` of every parameter of every deterministic effect (covariance order)."""
        return [f"{triad}.{name}" for triad in TRIADS for e in _deterministic(getattr(self, triad))
                for name in e.param_names()]

    def parameters(self) -> np.ndarray:
        return np.concatenate([e.params() for triad in TRIADS for e in _deterministic(getattr(self, triad))] or
                              [np.zeros(0)])

    def _slice(self, triad: str, kind: str) -> slice | None:
        i = 0
        for tr in TRIADS:
            for e in _deterministic(getattr(self, tr)):
                n = e.params().size
                if tr == triad and e.kind == kind:
                    return slice(i, i + n)
                i += n
        return None

    def effect(self, triad: str, kind: str) -> Effect | None:
        """The (first) effect of ``kind`` in ``triad``, or None."""
        return next((e for e in getattr(self, triad) if e.kind == kind), None)

    def has(self, triad: str, kind: str) -> bool:
        return self.effect(triad, kind) is not None

    def value(self, triad: str, kind: str) -> np.ndarray:
        """Parameters of effect ``kind`` (zeros(3) for an absent linear effect: it is not there)."""
        e = self.effect(triad, kind)
        if e is None:
            if kind in _LINEAR:
                return np.zeros(3)
            raise GyrosimError(f"the calibration has no {triad} {kind!r}")
        return e.params()

    def std(self, triad: str, kind: str) -> np.ndarray:
        """1σ of effect ``kind`` from the covariance (NaN where unknown; zeros for an absent linear effect)."""
        s = self._slice(triad, kind)
        if s is None:
            return np.zeros(3) if kind in _LINEAR else np.full(0, np.nan)
        return np.sqrt(np.clip(np.diag(self.covariance)[s], 0.0, None))  # NaN stays NaN

    def block_covariance(self, items: list[tuple[str, str]]) -> np.ndarray:
        """Covariance of the concatenated parameters of ``[(triad, kind), ...]`` (zeros for absent effects)."""
        idx, sizes = [], []
        for triad, kind in items:
            s = self._slice(triad, kind)
            idx.append(None if s is None else np.arange(s.start, s.stop))
            sizes.append(3 if s is None else s.stop - s.start)
        n = sum(sizes)
        out = np.zeros((n, n))
        offs = np.concatenate([[0], np.cumsum(sizes)])
        for i, ii in enumerate(idx):
            for j, jj in enumerate(idx):
                if ii is not None and jj is not None:
                    out[offs[i]:offs[i + 1], offs[j]:offs[j + 1]] = self.covariance[np.ix_(ii, jj)]
        return out

    # ---- the gyro's linear model (Zhou 2020 eq. 1), the names every caller used before
    @property
    def bias_rad_s(self) -> np.ndarray:
        return self.value("gyro", "bias")

    @property
    def scale_factor(self) -> np.ndarray:
        return self.value("gyro", "scale_factor")

    @property
    def nonorthogonality(self) -> np.ndarray:
        return self.value("gyro", "nonorthogonality")

    @property
    def bias_std_rad_s(self) -> np.ndarray:
        return self.std("gyro", "bias")

    @property
    def scale_factor_std(self) -> np.ndarray:
        return self.std("gyro", "scale_factor")

    @property
    def nonorthogonality_std(self) -> np.ndarray:
        return self.std("gyro", "nonorthogonality")

    def vector(self, triad: str = "gyro") -> np.ndarray:
        """(b, S, G) of ``triad`` (9,), the order of :meth:`linear_covariance`."""
        return np.concatenate([self.value(triad, k) for k in LINEAR_KINDS])

    def linear_covariance(self, triad: str = "gyro") -> np.ndarray:
        """Covariance (9, 9) of :meth:`vector`."""
        return self.block_covariance([(triad, k) for k in LINEAR_KINDS])

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    # ------------------------------------------------------------------ use
    def sensor_model(self):
        """The deterministic effects as a :class:`~gyrosim.sensor_model.SensorModel` (for compensation): the
        :attr:`applied` linear model of both triads when there is one, else every estimated effect."""
        from .sensor_model import SensorModel

        if self.applied is not None:
            return SensorModel(name=f"calibration ({self.method or 'unnamed'}, applied)",
                               gyro=self.applied.effects("gyro"), accelerometer=self.applied.effects("accelerometer"))
        return SensorModel(name=f"calibration ({self.method or 'unnamed'})", gyro=_deterministic(self.gyro),
                           accelerometer=_deterministic(self.accelerometer))

    def compensate(self, rec: Recording) -> Recording:
        """The recording with both triads compensated: the true rate and specific force this calibration
        implies, ω = (I + S_g + N(G_g))⁻¹(ω̃ − b_g), f likewise (effects inverted by the vocabulary;
        the accelerometer first, so effects that need the specific force see the compensated one).

        With an :attr:`applied` block, its values (the parameters the session determined, the prior's for the
        rest); without one, every estimated effect.  ``rec`` is not modified.  The result's metadata names the
        calibration and what it applied; a simulated recording's ``sensor_model`` (the device before compensation)
        moves to ``sensor_model_before_compensation``.
        """
        model = self.sensor_model()
        ctx = SignalContext(rec.t_s, rec.gyro_rad_s, rec.acc_m_s2, rec.temp_c, None, rec.mag_ut)
        acc = model.compensate_triad("accelerometer", rec.acc_m_s2, ctx) if model.accelerometer else rec.acc_m_s2
        ctx = replace(ctx, specific_force_true_m_s2=acc)
        gyro = model.compensate_triad("gyro", rec.gyro_rad_s, ctx) if model.gyro else rec.gyro_rad_s
        meta = dict(rec.meta)
        if "sensor_model" in meta:
            meta["sensor_model_before_compensation"] = meta.pop("sensor_model")
        meta["compensated_by"] = {"format": CALIBRATION_FORMAT, "version": CALIBRATION_VERSION, "method": self.method,
                                  "status": self.status, "parameters": dict(zip(self.parameter_names(),
                                                                                self.parameters().tolist()))}
        if self.applied is not None:
            meta["compensated_by"]["applied"] = self.applied.to_dict()
        return replace(rec, gyro_rad_s=gyro, acc_m_s2=acc, meta=meta)

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict[str, Any]:
        """The JSON layout (keys are a promise to users' scripts; see module docstring)."""
        d: dict[str, Any] = {"format": CALIBRATION_FORMAT, "version": CALIBRATION_VERSION, "method": self.method,
                             "status": self.status}
        for triad in TRIADS:
            if triad == "accelerometer" and not any(self.has(triad, k) for k in _LINEAR):
                continue  # not estimated (e.g. assumed calibrated): no block of zeros that look exact
            block: dict[str, Any] = {}
            std: dict[str, Any] = {}
            for kind, key in _SUMMARY[triad]:
                block[key] = self.value(triad, kind)
                std[key] = self.std(triad, kind)
            for e in getattr(self, triad):   # the gyro's rotation against the accelerometer, when estimated
                if e.kind in _EXTRA_SUMMARY.get(triad, {}):
                    key = _EXTRA_SUMMARY[triad][e.kind]
                    block[key], std[key] = self.value(triad, e.kind), self.std(triad, e.kind)
            block["std"] = std
            if self.applied is not None:   # which of these values the session determined (applied: the block below)
                i = TRIADS.index(triad) * 9
                block["determined"] = {key: self.applied.determined[i + 3 * j:i + 3 * j + 3].tolist()
                                       for j, (_, key) in enumerate(_SUMMARY[triad])}
            d[triad] = block
        if self.applied is not None:
            d["applied"] = self.applied.to_dict()
        d.update({k: v for k, v in self.diagnostics.items() if k not in d})
        d["warnings"] = list(self.warnings)
        d["frames"] = FRAMES
        d["effects"] = {triad: [e.to_dict() for e in getattr(self, triad)] for triad in TRIADS}
        d["parameters"] = self.parameter_names()
        d["covariance"] = self.covariance
        d.update(self.report)   # after the estimate, in the order the run added them (REPORT_SECTIONS)
        nan_paths: list[str] = []
        out = _clean(d, "", nan_paths)
        other = [p for p in nan_paths if not (p.startswith("covariance") or ".std." in p)]
        if other:
            out["warnings"].append(f"not a number, written as null: {', '.join(other[:6])}"
                                   f"{' …' if len(other) > 6 else ''}")
        return out

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text (indent 2; non-ASCII characters such as µ and σ as themselves)."""
        return json.dumps(self.to_dict(), indent=2, ensure_ascii=False, allow_nan=False)

    def save(self, path: str | Path) -> Path:
        """Write :meth:`to_json` and a newline to ``path`` as UTF-8 (temporary file, then rename: never
        half-written; :func:`gyrosim.outputs.write_text_atomic`).  ``calib run --json`` writes exactly these bytes."""
        from .outputs import write_text_atomic

        return write_text_atomic(Path(path), self.to_json() + "\n")

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Calibration":
        """Inverse of :meth:`to_dict` (the ``effects`` and ``covariance`` keys are authoritative)."""
        if d.get("format") != CALIBRATION_FORMAT:
            raise GyrosimError(f"not a calibration file: format {d.get('format')!r}, expected {CALIBRATION_FORMAT!r}; "
                               "pass the JSON calib run --json wrote, or calib demo's report.json")
        version = d.get("version")
        if not isinstance(version, int) or version > CALIBRATION_VERSION or version < 1:
            raise GyrosimError(f"calibration format version {version!r} is not supported (this gyrosim reads 1–"
                               f"{CALIBRATION_VERSION}); upgrade gyrosim")
        effects = d.get("effects") or {}
        gyro = tuple(effect_from_dict(e) for e in effects.get("gyro", []))
        acc = tuple(effect_from_dict(e) for e in effects.get("accelerometer", []))
        cov = d.get("covariance")
        cov = None if cov is None else np.array([[np.nan if v is None else v for v in row] for row in cov], float)
        known = {"format", "version", "method", "status", "warnings", "frames", "effects", "parameters", "covariance",
                 "gyro", "accelerometer", "applied", *REPORT_SECTIONS}
        diagnostics = {k: v for k, v in d.items() if k not in known}
        out = cls(gyro=gyro, accelerometer=acc, covariance=cov, status=d.get("status", "ok"),
                  warnings=tuple(w for w in d.get("warnings", []) if not w.startswith("not a number, written as null")),
                  method=d.get("method", ""), diagnostics=diagnostics,
                  report={k: d[k] for k in d if k in REPORT_SECTIONS}, applied=_applied_from(d))
        if d.get("parameters") is not None and list(d["parameters"]) != out.parameter_names():
            raise GyrosimError(
                "calibration file: 'parameters' does not match its effects; the file was edited by hand?"
            )
        return out

    @classmethod
    def from_json(cls, text: str) -> "Calibration":
        """The calibration in ``text``: a calibration JSON (:meth:`to_json`), or a report that carries one under
        ``"calibration"`` (``calib demo``'s ``report.json``)."""
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise GyrosimError(f"not a calibration JSON: {exc}") from exc
        if not isinstance(d, Mapping):
            raise GyrosimError(f"not a calibration JSON: its top level is a {type(d).__name__}, not an object; pass "
                               "the JSON calib run --json wrote, or calib demo's report.json")
        inner = d.get("calibration")
        if d.get("format") != CALIBRATION_FORMAT and isinstance(inner, Mapping) and \
                inner.get("format") == CALIBRATION_FORMAT:
            d = inner  # a report around its calibration (calib demo's report.json)
        return cls.from_dict(d)

    @classmethod
    def load(cls, path: str | Path) -> "Calibration":
        path = Path(path)
        if not path.is_file():
            raise GyrosimError(f"no such calibration file: {path}")
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise GyrosimError(f"{path} is not a calibration JSON (not UTF-8 text: {exc.reason}); pass the file "
                               "calib run --json wrote") from exc
        return cls.from_json(text)


def _applied_from(d: Mapping[str, Any]) -> Applied | None:
    """The ``applied`` block of a calibration JSON with the ``determined`` flags of its summary blocks (an
    accelerometer block absent: not determined), or None for a file without one."""
    if not isinstance(d.get("applied"), Mapping):
        return None
    flags = []
    for triad in TRIADS:
        det = ((d.get(triad) or {}).get("determined")) or {}
        for _, key in _SUMMARY[triad]:
            flags += [bool(v) for v in (det.get(key) or [False] * 3)]
    return Applied.from_dict(d["applied"], np.array(flags, bool))


def truth_calibration(rec: Recording, *, linear_only: bool = True) -> Calibration | None:
    """The oracle: the simulated device's own effects (stored in a gyrosim recording's metadata) as a
    :class:`Calibration` with zero covariance; None for a measured recording.

    Only tests and scoring (campaigns, Monte Carlo) may ask for it — an estimator under test must not.
    ``linear_only``: the bias, scale-factor and non-orthogonality effects (summed per kind), the model
    calib estimates; else every deterministic error-stage effect.
    """
    from .sensor_model import stored_sensor_model

    model = stored_sensor_model(rec.meta or {})
    if model is None:
        return None
    out = {}
    for triad in TRIADS:
        effs = [e for e in model.effects(triad) if e.stage == "error" and not e.stochastic]
        if linear_only:
            sums = {}
            for e in effs:
                if e.kind in _LINEAR:
                    sums[e.kind] = sums.get(e.kind, np.zeros(3)) + e.params()
            out[triad] = tuple(_LINEAR[k](value=v) for k, v in sums.items())
        else:
            out[triad] = tuple(effs)
    n = sum(e.params().size for t in TRIADS for e in out[t])
    return Calibration(gyro=out["gyro"], accelerometer=out["accelerometer"], covariance=np.zeros((n, n)),
                       method="truth (simulator)")
