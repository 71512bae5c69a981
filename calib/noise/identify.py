"""``calib noise``: the stochastic model of a static record, per axis, with intervals, in every unit,
as vocabulary effects (a ``SensorModel`` that ``gyrosim simulate --sensor`` reads).

Consistency check (σ must be honest): under the chosen model the weighted objective is
approximately χ² with J − p degrees of freedom (J scales, p parameters) when the scales were
independent; with their correlation its mean is tr(ΩΣ) − optimism/2.  An axis whose objective
exceeds the 99.9 % point of a χ²_{J−p} scaled to that mean is ``inconsistent``: no candidate
describes the record (e.g. a temperature ramp, a periodic disturbance), and the status is not ok.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrosim.lazy import lazy_module

from calib.noise.gmwm import AxisSelection, identify_axis
from calib.noise.units import CONVENTION, representations, si_unit

# imported on first use (gyrosim.lazy), so that start-up and a refused file do not pay for it
stats = lazy_module("scipy.stats")

__all__ = ["NoiseParameter", "AxisNoise", "NoiseIdentification", "identify_noise", "minimum_samples", "TRIADS"]

TRIADS = {"gyro": "gyro_rad_s", "acc": "acc_m_s2"}
TRIAD_NAME = {"gyro": "gyro", "acc": "accelerometer"}
Z95 = 1.959963984540054


@dataclass(frozen=True)
class NoiseParameter:
    """One parameter of the chosen model: SI value, 95 % interval (log-normal, from the sandwich
    covariance of log θ̂) and the relative 1σ (σ of log θ̂)."""

    kind: str
    field: str
    index: int          # which term of this kind (0, 1 for two Gauss–Markov processes)
    value: float
    ci95: tuple[float, float]
    rel_sigma: float
    unit: str

    def to_dict(self, rate_hz: float, triad: str) -> dict:
        return {"term": self.kind, "parameter": self.field, "index": self.index, "value_si": self.value,
                "unit_si": self.unit, "ci95_si": list(self.ci95), "relative_sigma": self.rel_sigma,
                "units": representations(self.kind, self.field, self.value, rate_hz, triad),
                "ci95_units": [representations(self.kind, self.field, v, rate_hz, triad) for v in self.ci95]}


@dataclass(frozen=True)
class AxisNoise:
    """The noise model chosen for one axis: its parameters with intervals, the model selection behind it,
    and whether the objective is consistent with the model (its p-value; module docstring)."""

    axis: str
    selection: AxisSelection = field(repr=False)
    parameters: tuple[NoiseParameter, ...]
    consistent: bool
    objective_p_value: float

    @property
    def model(self) -> str:
        return self.selection.chosen.name

    def value(self, kind: str, fld: str, index: int = 0) -> float:
        for p in self.parameters:
            if (p.kind, p.field, p.index) == (kind, fld, index):
                return p.value
        return 0.0


@dataclass(frozen=True)
class NoiseIdentification:
    """Result of :func:`identify_noise` for one triad."""

    triad: str
    rate_hz: float
    duration_s: float
    axes: tuple[AxisNoise, ...]
    warnings: tuple[str, ...] = ()
    inflation: dict = field(default_factory=dict)

    @property
    def status(self) -> str:
        return "ok" if all(a.consistent for a in self.axes) else "inconsistent"

    def sensor_model_dict(self, name: str = "identified") -> dict:
        """The chosen models as vocabulary effects (SI, :meth:`gyrosim.sensor_model.SensorModel.from_dict`
        layout).  Axes that chose different models share the union of terms; a term an axis lacks is 0."""
        keys: list[tuple[str, int]] = []
        for a in self.axes:
            for p in a.parameters:
                if (p.kind, p.index) not in keys:
                    keys.append((p.kind, p.index))
        effects = []
        for kind, idx in keys:
            from calib.noise.gmwm import NOISE_TERMS

            cls = NOISE_TERMS[kind]
            d: dict = {"effect": kind}
            for f in cls.noise_parameters:
                vals = [a.value(kind, f, idx) for a in self.axes]
                if f == "tau_s":  # an axis without this process: any τ (its σ is 0)
                    fill = max(vals) or 1.0
                    vals = [v or fill for v in vals]
                d[f] = vals
            effects.append(d)
        triad = TRIAD_NAME[self.triad]
        return {"name": name, "description": f"stochastic model identified by calib noise ({triad})",
                "source": "calib noise (GMWM, WIC selection)", "notes": {}, "temperature_range_c": [-40.0, 85.0],
                "thermal": None, "gyro": effects if triad == "gyro" else [],
                "accelerometer": effects if triad == "accelerometer" else []}

    def to_dict(self) -> dict:
        triad = TRIAD_NAME[self.triad]
        axes = []
        for a in self.axes:
            sel = a.selection
            axes.append({
                "axis": a.axis, "model": a.model, "consistent": a.consistent, "objective_p_value": a.objective_p_value,
                "parameters": [p.to_dict(self.rate_hz, triad) for p in a.parameters],
                "candidates": sorted(({"model": f.name, "parameters": f.p, "objective": f.objective,
                                       "optimism": f.optimism, "wic": f.wic} for f in sel.candidates),
                                     key=lambda c: c["wic"]),
                "wavelet_variance": {**sel.wv.to_dict(), "model": sel.chosen.nu2_model.tolist(),
                                     "sigma": np.sqrt(np.diag(sel.sigma)).tolist()},
            })
        return {"triad": triad, "rate_hz": self.rate_hz, "duration_s": self.duration_s, "status": self.status,
                "conventions": CONVENTION,
                "method": "Haar MODWT wavelet variance; GMWM fit (Guerrier et al. 2013); model chosen by WIC "
                          "(objective + analytic optimism 2tr(ΩDB⁻¹DᵀΩΣ)) with the one-standard-error rule; "
                          "95 % intervals log-normal from the sandwich covariance",
                "axes": axes, "inflation": self.inflation, "warnings": list(self.warnings),
                "sensor_model": self.sensor_model_dict()}


def minimum_samples(n_params: int) -> int:
    """Samples needed to fit a model with ``n_params`` parameters: J ≥ p + 2 octave scales with the
    largest Allan cluster ≤ T/8 (:func:`calib.noise.wavelet.scales_for`), so n ≥ 8·2^{p+1}."""
    return 8 * 2 ** (n_params + 1)


def _axis_result(axis: str, sel: AxisSelection) -> AxisNoise:
    c = sel.chosen
    sd = np.sqrt(np.clip(np.diag(c.cov_log), 0, None)) if c.cov_log is not None else np.full(c.p, np.nan)
    params, seen = [], {}
    for i, (kind, fld) in enumerate(c.names):
        idx = seen.get((kind, fld), 0)
        seen[(kind, fld)] = idx + 1
        v = float(math.exp(c.log_params[i]))
        lo, hi = (float(math.exp(c.log_params[i] - Z95 * sd[i])), float(math.exp(c.log_params[i] + Z95 * sd[i])))
        params.append(NoiseParameter(kind, fld, idx, v, (lo, hi), float(sd[i]), ""))
    # consistency: objective vs a χ² of J − p dof scaled to its expected mean tr(ΩΣ) − optimism/2
    j = sel.wv.m.size
    mean = float(np.sum(np.diag(sel.sigma) / np.diag(sel.sigma))) - c.optimism / 2
    dof = max(j - c.p, 1)
    pval = float(stats.chi2.sf(c.objective * dof / max(mean, 1e-9), dof))
    return AxisNoise(axis, sel, tuple(params), pval > 1e-3, pval)


def identify_noise(x: np.ndarray | list[np.ndarray], rate_hz: float, triad: str = "gyro",
                   models: list[tuple[str, ...]] | None = None, warnings: tuple[str, ...] = ()) -> NoiseIdentification:
    """Identify the stochastic model of each axis of ``x`` (N, 3) sampled at ``rate_hz`` (static),
    or of a list of separate still segments (K_i, 3) of one record (wavelet variances pooled)."""
    from calib.noise.wavelet import pooled_wavelet_variance

    segments = [np.asarray(s, float) for s in x] if isinstance(x, list) else None
    x = np.concatenate(segments) if segments is not None else np.asarray(x, float)
    dt = 1.0 / rate_hz
    axes = []
    for i in range(x.shape[1]):
        wv = pooled_wavelet_variance([s[:, i] for s in segments], dt) if segments is not None else None
        sel = identify_axis(x[:, i], dt, models, wv=wv)
        res = _axis_result("xyz"[i], sel)
        tri = TRIAD_NAME[triad]
        res = AxisNoise(res.axis, sel, tuple(NoiseParameter(p.kind, p.field, p.index, p.value, p.ci95, p.rel_sigma,
                                                            si_unit(p.kind, p.field, tri)) for p in res.parameters),
                        res.consistent, res.objective_p_value)
        axes.append(res)
    from calib.noise.inflation import inflation_table

    infl = inflation_table(axes, rate_hz)
    return NoiseIdentification(triad, float(rate_hz), x.shape[0] / rate_hz, tuple(axes), tuple(warnings), infl)

