"""Temperature-drift compensation of a gyro: fit on some temperature cycles, judge on others.

Every method is a set of effects from the shared vocabulary (so what is fitted here can be
injected by gyrosim, compensated by ``SensorModel.compensate_triad``, and proposed by
``calib closeloop``).  Fitted on a static recording (true rate 0, Earth rate aside) where the
gyro output is its bias b(T, Ṫ) plus noise; the design is each effect's ``sensitivity`` at zero
rate, solved by least squares on 10 s block means (the temperature moves ≤ 0.05 °C in a block at
18 °C/h):

| method | effects | source |
|---|---|---|
| ``none`` | bias (the training mean: a one-temperature calibration) | — |
| ``polynomial`` | bias + temperature_bias, degree 1–5 by leave-one-cycle-out CV | common practice |
| ``piecewise_linear`` | bias values at points every ``pwl_step_c``, linear between | FOG IMU calibration note, §4 |
| ``rbf`` | Gaussian RBF on (ΔT, ΔT²), 8 centres, output layer by least squares | MTEA temperature-drift paper, §3.2 |
| ``polynomial+dT/dt`` | polynomial + thermal_hysteresis h·LP_τ(dT/dt), τ by CV | heating/cooling hysteresis |

Metrics on the held-out record (residual r = y − b̂):

* held-out residual RMS (°/s);
* bias stability BS (°/h): the standard deviation of the 10 s means of r (the "zero-bias stability" of GJB 2426A / IEEE
  952 practice that "Modification of MTEA-Based Temperature Drift Error Compensation Model for MEMS-Gyros" reports,
  before/after compensation);
* Allan deviation of r: its minimum over τ (the bias-instability floor, °/h) and its value at τ = 1000 s, where an
  uncompensated temperature drift dominates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrosim import effects as E
from gyrosim.effects import Effect, SignalContext
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.sensor_model import SensorModel
from gyrosim.units import RAD_S_TO_DEG_H as DEG_H

from calib.temperature.timeblocks import block_means, time_block_index

__all__ = [
    "METHODS",
    "ThermalCompensation",
    "fit_compensation",
    "fit_methods",
    "evaluate",
    "compare_methods",
    "split_cycles",
]

METHODS = ("none", "polynomial", "piecewise_linear", "rbf", "polynomial+dT/dt")
BLOCK_S = 10.0


@dataclass(frozen=True)
class ThermalCompensation:
    """A fitted temperature model: vocabulary effects (SI) of the gyro triad, and how it was chosen."""

    method: str
    effects: tuple[Effect, ...]
    detail: str = ""
    notes: tuple[str, ...] = field(default_factory=tuple)

    def bias_rad_s(self, rec: Recording) -> np.ndarray:
        """b̂(T, Ṫ) (N, 3) rad/s on the recording's temperature channel."""
        ctx = _ctx(rec)
        zero = np.zeros((rec.t_s.size, 3))
        return sum((e.delta(zero, ctx) for e in self.effects), np.zeros((rec.t_s.size, 3)))

    def compensate(self, rec: Recording) -> Recording:
        """A new Recording with the model undone on the gyro (rate-dependent terms included);
        the input is untouched and the model is recorded in ``meta['temperature_compensation']``."""
        ctx = _ctx(rec)
        model = SensorModel(name=f"temperature:{self.method}", gyro=self.effects)
        gyro = model.compensate_triad("gyro", np.asarray(rec.gyro_rad_s), ctx)
        meta = {**rec.meta, "temperature_compensation": {"method": self.method, "detail": self.detail,
                                                         "effects": [_jsonable(e.to_dict()) for e in self.effects]}}
        return rec.with_signals(gyro_rad_s=gyro, meta=meta)


def _jsonable(d: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}


def _check_temperature(rec: Recording) -> np.ndarray:
    if rec.temp_c is None:
        raise RecordingError("the recording has no temperature channel (/temp, °C): a temperature model needs one")
    temp = np.asarray(rec.temp_c)
    bad = ~np.isfinite(temp)
    if bad.any():
        raise RecordingError(f"the temperature channel has {int(bad.sum())} NaN sample(s) (first at t = "
                             f"{rec.t_s[np.argmax(bad)]:.1f} s): interpolate or cut them before fitting")
    return temp


def _ctx(rec: Recording) -> SignalContext:
    temp = _check_temperature(rec)
    n = rec.t_s.size
    return SignalContext(
        t_s=rec.t_s,
        omega_true_rad_s=np.zeros((n, 3)),
        specific_force_true_m_s2=np.asarray(rec.acc_m_s2),
        temperature_c=temp,
    )


def _blocks(rec: Recording, block_s: float = BLOCK_S) -> tuple[np.ndarray, np.ndarray]:
    """Block index of each sample and the block-mean gyro (B, 3) of the non-empty blocks."""
    k = time_block_index(rec.t_s, block_s)
    means, counts = block_means(k, rec.gyro_rad_s)
    return k, means[counts > 0]


def _design(protos: list[Effect], rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Per-block regressors (B, 3, P) of the effects at zero rate, and the block means (B, 3)."""
    ctx = _ctx(rec)
    zero = np.zeros((rec.t_s.size, 3))
    reg = np.concatenate([e.sensitivity(zero, ctx) for e in protos], axis=2)
    k, y = _blocks(rec)
    rb, counts = block_means(k, reg)
    return rb[counts > 0], y


def _solve_axes(reg: np.ndarray, y: np.ndarray, ridge: float = 0.0) -> np.ndarray:
    """θ minimising Σ_axes ‖y_a − R_a θ‖² (+ ridge ‖θ‖² on scaled columns)."""
    a = reg.transpose(1, 0, 2).reshape(-1, reg.shape[2])
    b = y.T.reshape(-1)
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    a_s = a / scale
    if ridge:
        a_s = np.vstack([a_s, math.sqrt(ridge) * np.eye(a.shape[1])])
        b = np.concatenate([b, np.zeros(a.shape[1])])
    theta, *_ = np.linalg.lstsq(a_s, b, rcond=None)
    return theta / scale


def _with(protos: list[Effect], theta: np.ndarray) -> tuple[Effect, ...]:
    out, i = [], 0
    for e in protos:
        p = e.params().size
        out.append(e.with_params(theta[i : i + p]))
        i += p
    return tuple(out)


def split_cycles(rec: Recording) -> list[Recording]:
    """The recording cut at the chamber cycle starts of ``meta['chamber']`` (gyrosim.chamber)."""
    ch = rec.meta.get("chamber")
    if not ch or len(ch.get("cycle_starts_s", [])) < 2:
        raise RecordingError("the recording has no chamber cycles to hold out (it is not a gyrosim chamber recording "
                             "of two or more cycles): train on a separate recording of the same IMU instead "
                             "(calib temperature --train RECORDING)")
    edges = list(ch["cycle_starts_s"]) + [math.inf]
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        m = (rec.t_s >= a) & (rec.t_s < b)
        out.append(_cut(rec, m))
    return out


def _cut(rec: Recording, m: np.ndarray) -> Recording:
    tr = rec.truth
    return Recording(
        t_s=rec.t_s[m],
        gyro_rad_s=rec.gyro_rad_s[m],
        acc_m_s2=rec.acc_m_s2[m],
        temp_c=None if rec.temp_c is None else rec.temp_c[m],
        meta=rec.meta,
        truth=None
        if tr is None
        else type(tr)(
            **{
                k: (None if getattr(tr, k) is None else getattr(tr, k)[m])
                for k in ("omega_body_rad_s", "specific_force_body_m_s2", "quat_nb", "position_nav_m")
            }
        ),
    )


def _concat(recs: list[Recording]) -> Recording:
    return Recording(t_s=np.concatenate([r.t_s for r in recs]), gyro_rad_s=np.concatenate([r.gyro_rad_s for r in recs]),
                     acc_m_s2=np.concatenate([r.acc_m_s2 for r in recs]),
                     temp_c=np.concatenate([r.temp_c for r in recs]), meta=recs[0].meta)


def _poly_protos(degree: int, t_ref: float, rng: tuple[float, float]) -> list[Effect]:
    return [E.Bias(), E.TemperatureBias(coefficients=np.zeros((3, degree)), t_ref_c=t_ref, range_c=rng)]


def _cv_rms(protos_of, train_cycles: list[Recording]) -> float:
    """Leave-one-cycle-out RMS of the block-mean residual (contiguous halves if one cycle)."""
    folds = train_cycles if len(train_cycles) >= 2 else _halves(train_cycles[0])
    err = []
    for k, test in enumerate(folds):
        train = _concat([f for j, f in enumerate(folds) if j != k])
        protos = protos_of(train)
        reg, y = _design(protos, train)
        theta = _solve_axes(reg, y)
        comp = ThermalCompensation("cv", _with(protos, theta))
        r = test.gyro_rad_s - comp.bias_rad_s(test)
        err.append(float(np.mean(_blocks(test.with_signals(gyro_rad_s=r))[1] ** 2)))
    return math.sqrt(float(np.mean(err)))


def _halves(rec: Recording) -> list[Recording]:
    mid = rec.t_s[0] + 0.5 * (rec.t_s[-1] - rec.t_s[0])
    return [_cut(rec, rec.t_s < mid), _cut(rec, rec.t_s >= mid)]


def fit_compensation(train: Recording | list[Recording], method: str, *, pwl_step_c: float = 15.0,
                     rbf_centres: int = 8, max_degree: int = 5) -> ThermalCompensation:
    """Fit one method (module docstring) on static training data (one recording or its cycles)."""
    if method not in METHODS:
        raise RecordingError(f"unknown temperature method {method!r}; choose from {', '.join(METHODS)}")
    cycles = train if isinstance(train, list) else [train]
    rec = _concat(cycles) if len(cycles) > 1 else cycles[0]
    temp = _check_temperature(rec)
    lo, hi = float(temp.min()), float(temp.max())
    span = hi - lo
    t_ref = 0.5 * (lo + hi)
    rng = (lo - 1e3, hi + 1e3)  # the model holds what it fitted; range checks are the data's job here
    notes: list[str] = []
    if method != "none" and span < 2.0:
        raise RecordingError(f"temperature span {span:.2f} °C is too small to fit a temperature model "
                             f"({method}): it needs ≥ 2 °C; record a warm-up or a chamber cycle")
    if method == "none":
        protos: list[Effect] = [E.Bias()]
        detail = "constant bias (training mean)"
    elif method in ("polynomial", "polynomial+dT/dt"):
        max_d = max(1, min(max_degree, int(span // 5)))
        cvs = [_cv_rms(lambda r, d=d: _poly_protos(d, t_ref, rng), cycles) for d in range(1, max_d + 1)]
        # the lowest degree within 1 % of the best CV error: a higher one that gains less is noise-fitting
        degree = int(np.flatnonzero(np.array(cvs) <= 1.01 * min(cvs))[0]) + 1
        protos = _poly_protos(degree, t_ref, rng)
        detail = f"degree {degree} (CV RMS °/s by degree: {', '.join(f'{math.degrees(c):.4f}' for c in cvs)})"
        if method == "polynomial+dT/dt":
            taus = (60.0, 300.0, 600.0, 1800.0)
            cvh = [_cv_rms(lambda r, tau=tau: protos + [E.ThermalHysteresis(tau_s=tau)], cycles) for tau in taus]
            tau = taus[int(np.argmin(cvh))]
            protos = protos + [E.ThermalHysteresis(tau_s=tau)]
            detail += f"; dT/dt low-passed with τ = {tau:g} s (CV over {', '.join(f'{t:g}' for t in taus)} s)"
    elif method == "piecewise_linear":
        pts = np.arange(lo, hi + 1e-9, pwl_step_c)
        pts = np.append(pts, hi) if hi - pts[-1] > 1e-6 else pts
        k = pts.size
        protos = [E.TemperaturePiecewise(points_c=pts, bias=np.zeros((3, k)), scale=np.zeros((3, k)))]
        detail = (
            f"{k} points every {pwl_step_c:g} °C over {lo:.1f}…{hi:.1f} °C (scale columns: no rate, not identifiable)"
        )
    else:  # rbf
        centres = np.linspace(lo, hi, rbf_centres)
        protos = [E.Bias(), E.TemperatureRBF(centres_c=centres, width_c=float(centres[1] - centres[0]), t_ref_c=t_ref,
                                             weights=np.zeros((3, rbf_centres)))]
        detail = f"{rbf_centres} Gaussian centres on (ΔT, ΔT²), width {centres[1] - centres[0]:.1f} °C"
    reg, y = _design(protos, rec)
    theta = _solve_axes(reg, y, ridge=1e-10 if method == "rbf" else 0.0)
    return ThermalCompensation(method, _with(protos, theta), detail, tuple(notes))


@dataclass(frozen=True)
class Metrics:
    method: str
    held_out_rms_deg_s: float
    bias_stability_deg_h: float
    adev_min_deg_h: float
    adev_1000s_deg_h: float
    detail: str = ""


def evaluate(comp: ThermalCompensation | None, test: Recording, method: str = "") -> Metrics:
    """Held-out metrics of the residual y − b̂ on a static test recording (module docstring)."""
    from calib.noise.allan import allan_deviation

    r = np.asarray(test.gyro_rad_s) - (comp.bias_rad_s(test) if comp is not None else 0.0)
    rate = 1.0 / float(np.median(np.diff(test.t_s)))
    _, blocks = _blocks(test.with_signals(gyro_rad_s=r))
    bs = float(np.mean(np.std(blocks, axis=0, ddof=1))) * DEG_H
    curves = [allan_deviation(r[:, a], rate) for a in range(3)]
    adev_min = float(np.mean([c.adev.min() for c in curves])) * DEG_H
    adev_1000 = float(np.mean([np.interp(math.log(1000.0), np.log(c.tau_s), c.adev) for c in curves])) * DEG_H
    return Metrics(method or (comp.method if comp else "raw"), float(np.sqrt(np.mean(r**2))) * 180 / math.pi, bs,
                   adev_min, adev_1000, comp.detail if comp else "")


def fit_methods(train: list[Recording], methods: tuple[str, ...] = METHODS,
                extra: dict[str, ThermalCompensation] | None = None) -> dict[str, ThermalCompensation]:
    """Each method fitted on the training cycles (name → model), then the ``extra`` models as given."""
    return {**{m: fit_compensation(train, m) for m in methods}, **(extra or {})}


def compare_methods(train: list[Recording], test: list[Recording], methods: tuple[str, ...] = METHODS,
                    extra: dict[str, ThermalCompensation] | None = None,
                    fitted: dict[str, ThermalCompensation] | None = None) -> list[Metrics]:
    """Fit each method on the training cycles (or take them from ``fitted``, :func:`fit_methods`),
    evaluate on the held-out ones (their concatenation)."""
    held = _concat(test) if len(test) > 1 else test[0]
    fitted = fitted if fitted is not None else fit_methods(train, methods, extra)
    return [evaluate(comp, held, name if name not in methods else "") for name, comp in fitted.items()]
