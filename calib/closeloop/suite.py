"""The undeclared-effect suite of issue 5: does the loop find what the declared model lacks?

For each effect, the zhou2020 session (hand ``typical``) is corrupted by the consumer-grade
Zhou 2020 device (reading B: bias, scale factor, non-orthogonality, 0.5 °/√h white noise) *plus*
that effect; the calibrator is told only bias, scale factor and non-orthogonality.  Sizes are
consumer-MEMS datasheet orders of magnitude, raised where the zhou2020 schedule (rates ≤ 1.3 rad/s,
171 s) could not reveal a datasheet value at this noise — then the size is the schedule's
detection limit, which is itself a finding:

| effect | size | datasheet order |
|---|---|---|
| time_offset | 3.4 ms | 1–10 ms filter/bus latency |
| g_sensitivity | 0.08–0.12 °/s/g (diagonal) | MPU-9250 0.1 °/s/g |
| scale_nonlinearity | 1.5–2.5e-3 1/(rad/s) (≈ 1.7 % at 500 °/s) | 0.1–0.5 % FS; smaller is below this schedule's reach |
| misalignment | 2–6 mrad | cross-axis 1–2 % |
| temperature_bias | 0.02–0.03 °/s/°C over an 8 °C warm-up | MPU-9250 ±0.24 °/s/°C worst |
| temperature_scale | 2–3e-4 /°C | MPU-9255 ±4 % over 125 °C |
| random_walk | 0.005 °/s/√s (1080 °/h/√h) | worst consumer units |
| magnetic_sensitivity | 6e-4 °/s/µT (diagonal) | a gyro beside a magnetised part |

:func:`run_case` returns whether the loop named the effect first, its estimate against the truth
(z = (θ̂ − θ)/σ̂), and the held-out error of the loop's model against that of the correct model
(declared + the true effect kind, fitted the same way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrosim import effects as E
from gyrosim.recording import Recording
from gyrosim.sensor_model import SensorModel, load_sensor
from gyrosim.thermal import ThermalModel

from .loop import DEFAULT_DECLARED, CloseloopResult, run_closeloop

__all__ = ["SUITE", "BASE_SENSOR", "WARM_UP", "SuiteCase", "CaseResult", "sensor_with", "run_case"]

D = math.pi / 180.0
BASE_SENSOR = "zhou2020_sim_consumer"
WARM_UP = ThermalModel(ambient_c=25.0, self_heating_c=8.0, self_heating_tau_s=120.0, case_tau_s=30.0)


@dataclass(frozen=True)
class SuiteCase:
    effect: E.Effect
    thermal: ThermalModel | None = None


SUITE: dict[str, SuiteCase] = {
    "time_offset": SuiteCase(E.TimeOffset(delay_s=0.0034)),
    "g_sensitivity": SuiteCase(E.GSensitivity(value=np.diag([0.10, 0.08, 0.12]) * D / 9.80665)),
    "scale_nonlinearity": SuiteCase(E.ScaleNonlinearity(value=[2.0e-3, -1.5e-3, 2.5e-3])),
    "misalignment": SuiteCase(E.Misalignment(value=[0.005, -0.003, 0.004, 0.002, -0.006, 0.003])),
    "temperature_bias": SuiteCase(E.TemperatureBias(coefficients=np.array([[0.03], [-0.02], [0.025]]) * D), WARM_UP),
    "temperature_scale": SuiteCase(E.TemperatureScale(coefficients=np.array([[3e-4], [-2e-4], [2.5e-4]])), WARM_UP),
    "random_walk": SuiteCase(E.RandomWalk(value=np.full(3, 0.005 * D))),
    "magnetic_sensitivity": SuiteCase(E.MagneticSensitivity(value=np.diag([1.0, -1.0, 1.2]) * 6e-4 * D)),
}


def sensor_with(case: SuiteCase | None, base: str = BASE_SENSOR) -> SensorModel:
    """The base device plus the case's effect (and thermal model)."""
    s = load_sensor(base)
    if case is None:
        return s
    return replace(s, gyro=s.gyro + (case.effect,), thermal=case.thermal or s.thermal)


@dataclass(frozen=True)
class CaseResult:
    effect: str
    found: list[str]                 # in the order the loop added them
    named_first: bool
    z_max: float                     # max |θ̂ − θ| / σ̂ over the identifiable parameters
    estimate: np.ndarray
    truth: np.ndarray
    sigma: np.ndarray
    error_declared: float            # held-out residual RMS, °/s
    error_loop: float
    error_correct: float
    result: CloseloopResult

    @property
    def ratio_to_correct(self) -> float:
        return self.error_loop / self.error_correct


def _identifiable(kind: str, res: CloseloopResult, true_effect: E.Effect, device_nonortho: np.ndarray):
    """(estimate, truth, σ) of what the reference can identify: a misalignment's symmetric part
    trades with the declared non-orthogonality, so the total off-diagonal matrix is compared."""
    f = next(x for x in res.found if x.effect == kind)
    vals = np.array([v["value"] for v in f.params.values()])
    sig = np.array([v["sigma"] for v in f.params.values()])
    if kind == "misalignment":
        n_hat = np.array([res.declared_params[f"nonorthogonality.value[{i}]"]["value"] for i in range(3)])
        n_sig = np.array([res.declared_params[f"nonorthogonality.value[{i}]"]["sigma"] for i in range(3)])
        tot_hat = E._nonortho_matrix(n_hat) + E.Misalignment(value=vals).matrix()
        tot_true = E._nonortho_matrix(device_nonortho) + true_effect.matrix()
        sig_tot = np.hypot(E._nonortho_matrix(n_sig), E.Misalignment(value=sig).matrix())
        off = ~np.eye(3, dtype=bool)
        return tot_hat[off], tot_true[off], sig_tot[off]
    if kind == "random_walk":
        return vals, np.array([float(true_effect.value[0])]), sig
    return vals, np.asarray(true_effect.params()), sig


def run_case(kind: str, truth: Recording, seed: int, declared: tuple[str, ...] = DEFAULT_DECLARED) -> CaseResult:
    """Simulate one case on a truth recording (sensor noise from ``seed``) and run the loop."""
    case = SUITE[kind]
    sensor = sensor_with(case)
    from gyrosim.simulate import apply_sensor

    rec = apply_sensor(truth, sensor, np.random.default_rng(seed))
    res = run_closeloop(rec, declared)
    correct = run_closeloop(rec, tuple(declared) + (kind,), candidates=[])
    found = [f.effect for f in res.found]
    if kind in found:
        nonortho = next(e for e in sensor.gyro if e.kind == "nonorthogonality").params()
        est, tru, sig = _identifiable(kind, res, case.effect, nonortho)
        z = float(np.max(np.abs(est - tru) / sig))
    else:
        est = tru = sig = np.zeros(0)
        z = math.inf
    return CaseResult(kind, found, bool(found and found[0] == kind), z, est, tru, sig,
                      res.error_before["held_out_residual_rms"], res.error_after["held_out_residual_rms"],
                      correct.error_before["held_out_residual_rms"], res)
