"""A sensor model = an ordered list of effects per triad (gyro, accelerometer, magnetometer), plus presets.

Forward (simulation), per triad with true input x:

    u = x + Σ_{error effects} δ_i(x, ctx)        (order-free; slow random processes — flicker,
                                                   random walk, Gauss–Markov — are drawn on a
                                                   coarse grid where the triad's white noise
                                                   hides what it omits, Effect.coarse_step_s)
    y = T_m ∘ … ∘ T_1 (u)                          (output effects, in list order)

Compensation (estimation) undoes the deterministic part: the output effects in reverse order
(bandwidth and latency exactly; quantization left as is; saturated samples rejected), then
u = x + Σδ_i(x) is solved for x by Newton's method with J = I + Σ ∂δ_i/∂x (one step when every
effect is linear in x).  Random effects cannot be undone and are left as noise.

Presets are TOML files in ``gyrosim/presets/sensors/`` written in datasheet units; see
:func:`load_sensor` and docs/error-model.md for the layout.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._presets import builtin_names, load_named_toml
from .effects import EFFECTS, Effect, SignalContext, effect_from_dict
from .errors import GyrosimError, PresetError
from .lazy import lazy_module
from .thermal import ThermalModel

# imported on first use (gyrosim.lazy), so that start-up and a refused file do not pay for it
kern = lazy_module("gyrosim._kernels")

__all__ = ["SensorModel", "load_sensor", "sensor_preset_names", "stored_sensor_model", "TRIADS"]

TRIADS = ("gyro", "accelerometer", "magnetometer")

@dataclass(frozen=True)
class SensorModel:
    """Effects of the gyro, accelerometer and (optional) magnetometer triads, an optional thermal
    model, and provenance.  A model without magnetometer effects is a 6-axis IMU: a recording
    corrupted with it carries no ``/mag`` (the truth field stays in ``/truth/mag_field``)."""

    name: str = "truth"
    gyro: tuple[Effect, ...] = ()
    accelerometer: tuple[Effect, ...] = ()
    thermal: ThermalModel | None = None
    temperature_range_c: tuple[float, float] = (-40.0, 85.0)
    description: str = ""
    source: str = ""
    notes: dict[str, str] = field(default_factory=dict)
    magnetometer: tuple[Effect, ...] = ()  # µT; last so that positional construction keeps working

    def __post_init__(self) -> None:
        for triad in TRIADS:
            for e in getattr(self, triad):
                if triad not in e.triads:
                    raise PresetError(f"sensor {self.name!r}: effect {e.kind!r} does not apply to the {triad}")

    def effects(self, triad: str) -> tuple[Effect, ...]:
        if triad not in TRIADS:
            raise GyrosimError(f"triad must be one of {TRIADS}, got {triad!r}")
        return getattr(self, triad)

    @property
    def has_magnetometer(self) -> bool:
        return bool(self.magnetometer)

    def realize(self, rng: np.random.Generator) -> "SensorModel":
        """One device of this model: unit-to-unit random parameters (``*_sigma``) drawn.

        Streams: ``rng.spawn(2)`` → (gyro, accelerometer), then one more child for the
        magnetometer, so adding a magnetometer leaves the gyro and accelerometer draws unchanged."""
        streams = rng.spawn(2) + rng.spawn(1)
        out = {}
        for triad, r in zip(TRIADS, streams):
            effs = self.effects(triad)
            subs = r.spawn(len(effs)) if effs else []
            out[triad] = tuple(e.realize(s) for e, s in zip(effs, subs))
        return SensorModel(self.name, out["gyro"], out["accelerometer"], self.thermal,
                           self.temperature_range_c, self.description, self.source, dict(self.notes),
                           out["magnetometer"])

    # ---------------------------------------------------------------- forward
    def apply_triad(self, triad: str, x: np.ndarray, ctx: SignalContext, rng: np.random.Generator) -> np.ndarray:
        """Corrupt the true signal x (N, 3) of one triad. ``x`` is not modified."""
        effs = self.effects(triad)
        streams = rng.spawn(len(effs)) if effs else []
        x = np.ascontiguousarray(x, dtype=float)
        y = x.copy()
        white = sum((e.density for e in effs if e.is_white_noise), np.zeros(3))
        error = [(e, r) for e, r in zip(effs, streams) if e.stage == "error"]
        for e, r in error:
            if e.pointwise:
                continue
            step = e.coarse_step_s(white, ctx.dt_s) if e.stochastic else None
            factor = int(step // ctx.dt_s) if step is not None else 1
            if factor >= 4:  # slow process: draw on a coarse grid, interpolate linearly (Effect.coarse_step_s)
                coarse = e.delta_on_grid((x.shape[0] - 1) // factor + 2, factor * ctx.dt_s, r)
                kern.add_upsampled(y, np.ascontiguousarray(coarse), factor)
            else:
                e.add_delta(y, x, ctx, r)
        # constant affine effects (bias, scale, non-orthogonality, misalignment): one pass
        affine = [(e, ac) for e, ac in ((e, e.affine()) for e, _ in error if e.pointwise) if ac is not None]
        if affine:
            a_sum = sum(a for _, (a, _) in affine)
            c_sum = sum(c for _, (_, c) in affine)
            kern.add_affine(y, x, np.asarray(a_sum, float), np.asarray(c_sum, float))
        grouped = {id(e) for e, _ in affine}
        for e, r in error:  # the other pointwise effects: one in-place pass each (gyrosim._kernels)
            if e.pointwise and id(e) not in grouped:
                e.add_delta(y, x, ctx, r)
        for e, r in zip(effs, streams):
            if e.stage == "output":
                y = e.transform(y, ctx, r)
        return y

    def apply(self, ctx: SignalContext, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(gyro rad/s, accelerometer m/s²) measured from the truth in ``ctx``."""
        self.check_temperature(ctx)
        g_rng, a_rng = rng.spawn(2)
        return (
            self.apply_triad("gyro", ctx.omega_true_rad_s, ctx, g_rng),
            self.apply_triad("accelerometer", ctx.specific_force_true_m_s2, ctx, a_rng),
        )

    def apply_magnetometer(self, ctx: SignalContext, rng: np.random.Generator) -> np.ndarray:
        """Magnetometer output (µT, body frame) from the true field ``ctx.mag_body_ut``."""
        if not self.magnetometer:
            raise GyrosimError(f"sensor {self.name!r} has no magnetometer effects (a 6-axis model)")
        return self.apply_triad("magnetometer", ctx.require("mag_body_ut", "magnetometer"), ctx, rng)

    def check_temperature(self, ctx: SignalContext) -> None:
        if ctx.temperature_c is None:
            return
        lo, hi = self.temperature_range_c
        t = ctx.temperature_c
        if np.nanmin(t) < lo or np.nanmax(t) > hi:
            raise GyrosimError(
                f"sensor {self.name!r} is specified for {lo:g}–{hi:g} °C but the temperature reaches "
                f"{np.nanmin(t):.1f}–{np.nanmax(t):.1f} °C"
            )

    # ---------------------------------------------------------------- inverse
    def compensate_triad(
        self, triad: str, y: np.ndarray, ctx: SignalContext, *, tol: float = 1e-15, max_iter: int = 30
    ) -> np.ndarray:
        """Undo the deterministic effects of one triad: returns the estimated true signal."""
        effs = self.effects(triad)
        u = np.array(y, dtype=float, copy=True)
        for e in reversed([e for e in effs if e.stage == "output"]):
            if not e.stochastic:
                u = e.inverse(u, ctx)
        det = [e for e in effs if e.stage == "error" and not e.stochastic]
        if not det:
            return u
        x = u.copy()
        scale = max(1.0, float(np.abs(u).max()))
        for _ in range(max_iter):
            r = x + sum(e.delta(x, ctx) for e in det) - u
            jac = np.broadcast_to(np.eye(3), x.shape + (3,)).copy()
            for e in det:
                d = e.delta_dx(x, ctx)
                if d is not None:
                    jac = jac + d
            x = x - np.linalg.solve(jac, r[..., None])[..., 0]
            if np.abs(r).max() <= tol * scale:
                break
        return x

    # ---------------------------------------------------------------- description
    def to_dict(self) -> dict[str, Any]:
        d = {
            "name": self.name,
            "description": self.description,
            "source": self.source,
            "notes": self.notes,
            "temperature_range_c": list(self.temperature_range_c),
            "thermal": self.thermal.to_dict() if self.thermal else None,
            "gyro": [e.to_dict() for e in self.gyro],
            "accelerometer": [e.to_dict() for e in self.accelerometer],
        }
        if self.magnetometer:  # a 6-axis model's JSON stays as it was
            d["magnetometer"] = [e.to_dict() for e in self.magnetometer]
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "SensorModel":
        """Inverse of :meth:`to_dict` (SI values, as stored in recordings)."""
        return cls(
            name=d.get("name", "model"),
            gyro=tuple(effect_from_dict(e) for e in d.get("gyro", [])),
            accelerometer=tuple(effect_from_dict(e) for e in d.get("accelerometer", [])),
            thermal=ThermalModel(**d["thermal"]) if d.get("thermal") else None,
            temperature_range_c=tuple(d.get("temperature_range_c", (-40.0, 85.0))),
            description=d.get("description", ""),
            source=d.get("source", ""),
            notes=dict(d.get("notes", {})),
            magnetometer=tuple(effect_from_dict(e) for e in d.get("magnetometer", [])),
        )


# ================================================================ presets in datasheet units
def _effect_from_preset(triad: str, raw: dict[str, Any], where: str) -> Effect:
    raw = dict(raw)
    kind = raw.pop("effect", None)
    if kind not in EFFECTS:
        raise PresetError(f"{where}: unknown effect {kind!r}; known: {', '.join(EFFECTS)}")
    unit = raw.pop("unit", None)
    raw.pop("note", None)
    cls = EFFECTS[kind]
    quantity = cls.quantities.get(triad)
    if quantity is None:
        raise PresetError(f"{where}: effect {kind!r} does not apply to the {triad}")
    if unit is None:
        raise PresetError(f"{where}: effect {kind!r} needs a unit for {cls.param_fields[0]!r} "
                          "(e.g. one of its accepted units)")
    try:
        raw = cls.preset_to_si(raw, unit, quantity)
    except GyrosimError as exc:
        raise PresetError(f"{where}: {exc}") from exc
    try:
        return effect_from_dict({"effect": kind, **raw})
    except (TypeError, GyrosimError) as exc:
        raise PresetError(f"{where}: {exc}") from exc


_SENSOR_KEYS = {"name", "description", "source", "notes", "temperature_range_c", "thermal", "gyro", "accelerometer",
                "magnetometer", "extends"}


def _resolve_extends(data: dict[str, Any], name: str, seen: tuple[str, ...] = ()) -> dict[str, Any]:
    """A preset with ``extends = "base"`` is the base preset's table with this table's keys on top:
    a triad list given here replaces the base's list, ``notes`` are merged, every other key is
    replaced.  (The 9-axis ``mpu9250_9axis`` is ``mpu9250`` plus a magnetometer.)"""
    base_name = data.get("extends")
    if base_name is None:
        return data
    if base_name in seen:
        raise PresetError(f"sensor preset {name!r}: 'extends' loops through {' → '.join(seen + (base_name,))}")
    _, base = load_named_toml(("presets", "sensors"), base_name, "sensor preset (extends)", PresetError)
    base = _resolve_extends(base, base_name, seen + (name,))
    out = {k: v for k, v in base.items() if k != "name"}
    out.update({k: v for k, v in data.items() if k not in ("extends", "notes")})
    out["notes"] = {**base.get("notes", {}), **data.get("notes", {})}
    return out


def sensor_from_toml_dict(data: dict[str, Any], default_name: str) -> SensorModel:
    """Build a :class:`SensorModel` from a preset table in datasheet units."""
    bad = set(data) - _SENSOR_KEYS
    if bad:
        raise PresetError(f"sensor preset {default_name!r}: unknown key(s) {sorted(bad)}; allowed: "
                          f"{sorted(_SENSOR_KEYS)}")
    data = _resolve_extends(data, default_name)
    effects = {}
    for triad in TRIADS:
        effects[triad] = tuple(
            _effect_from_preset(triad, raw, f"sensor {default_name!r} {triad} effect {i + 1}")
            for i, raw in enumerate(data.get(triad, []))
        )
    thermal = ThermalModel(**data["thermal"]) if "thermal" in data else None
    return SensorModel(
        name=str(data.get("name", default_name)),
        gyro=effects["gyro"],
        accelerometer=effects["accelerometer"],
        thermal=thermal,
        temperature_range_c=tuple(data.get("temperature_range_c", (-40.0, 85.0))),
        description=str(data.get("description", "")),
        source=str(data.get("source", "")),
        notes={str(k): str(v) for k, v in data.get("notes", {}).items()},
        magnetometer=effects["magnetometer"],
    )


def sensor_preset_names() -> list[str]:
    """Names of the sensor presets shipped in ``gyrosim/presets/sensors/*.toml``."""
    return builtin_names("presets", "sensors")


def load_sensor(name_or_path: str | Path) -> SensorModel:
    """Load a sensor preset by name (``mpu9250``, ``zhou2020_sim``, ...), a TOML path, or a Kalibr
    ``imu.yaml`` (white noise and bias random walk of both triads, :func:`gyrosim.exchange.sensor_from_kalibr`)."""
    if str(name_or_path).lower().endswith((".yaml", ".yml")):
        from .exchange import sensor_from_kalibr

        return sensor_from_kalibr(name_or_path)
    if str(name_or_path).lower().endswith(".json"):
        return sensor_from_json(name_or_path)
    name, data = load_named_toml(("presets", "sensors"), name_or_path, "sensor preset", PresetError)
    return sensor_from_toml_dict(data, name)


def sensor_from_json(path: str | Path) -> SensorModel:
    """A sensor model in SI JSON: :meth:`SensorModel.to_dict` itself, or a result file that carries
    one under ``sensor_model`` (``calib noise --json``: the identified stochastic model)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PresetError(f"sensor file {path}: not readable JSON ({exc})") from exc
    if isinstance(data, dict) and isinstance(data.get("sensor_model"), dict):
        data = data["sensor_model"]
    if not isinstance(data, dict) or not (data.get("gyro") or data.get("accelerometer") or data.get("magnetometer")):
        raise PresetError(f"sensor file {path}: no sensor model (a JSON with 'gyro'/'accelerometer' effect lists, "
                          "or a calib noise result with 'sensor_model')")
    try:
        return SensorModel.from_dict(data)
    except (TypeError, KeyError, GyrosimError) as exc:
        raise PresetError(f"sensor file {path}: {exc}") from exc


def stored_sensor_model(meta: dict[str, Any]) -> SensorModel | None:
    """The exact device a simulated recording was corrupted with (``meta['sensor_model']``, a JSON
    string or, once read back from HDF5, a dict), or None for measured data or a truth recording."""
    raw = meta.get("sensor_model")
    if isinstance(raw, str):
        try:
            raw = json.loads(raw)
        except json.JSONDecodeError:
            return None
    if not isinstance(raw, dict) or "note" in raw and not (raw.get("gyro") or raw.get("accelerometer")):
        return None
    return SensorModel.from_dict(raw)
