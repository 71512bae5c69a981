"""The undeclared-effect suites: does the loop name the cause the declared model lacks, and never a proxy?

Each case corrupts a truth session with the consumer-grade Zhou 2020 device (reading B: bias,
scale factor, non-orthogonality, 0.5 °/√h white noise) *plus* undeclared effects; the calibrator
is told only bias, scale factor and non-orthogonality.  Sizes are consumer-MEMS datasheet orders,
raised where the schedule (rates ≤ 1.3 rad/s, 171 s) could not reveal a datasheet value at this
noise — then the size is the schedule's detection limit, which is itself a finding:

| effect | size | datasheet order |
|---|---|---|
| time_offset | 3.4 ms | 1–10 ms filter/bus latency |
| g_sensitivity | 0.08–0.12 °/s/g (diagonal) | MPU-9250 0.1 °/s/g |
| scale_nonlinearity | 1.5–2.5e-3 1/(rad/s) (≈ 1.7 % at 500 °/s) | 0.1–0.5 % FS; smaller: below this schedule's reach |
| scale_asymmetry | 1.0–2.0e-3 (scale ± 0.1–0.2 % by the rate's sign) | ≈ 4e-3 measured on a NilsPod's z axis |
| misalignment | 2–6 mrad | cross-axis 1–2 % |
| temperature_bias | 0.02–0.03 °/s/°C over an 8 °C warm-up | MPU-9250 ±0.24 °/s/°C worst |
| temperature_scale | 2–3e-4 /°C | MPU-9255 ±4 % over 125 °C |
| random_walk | 0.005 °/s/√s (1080 °/h/√h) | worst consumer units |
| magnetic_sensitivity | 6e-4 °/s/µT (diagonal) | a gyro beside a magnetised part |
| accelerometer thermal drift | 0.8–1.5 mg/°C | MPU-9250 ±1.5 mg/°C |

Magnetometer cases (:data:`MAG_SUITE`): the same gyro device, plus the MPU-9250's AK8963
magnetometer (``mpu9250_9axis``) reduced to its noise, quantisation and range (a calibrated
compass), plus one undeclared magnetometer effect; the declared magnetometer model is empty:

| effect | size | datasheet order |
|---|---|---|
| hard_iron | (40, −25, 60) µT | AK8963 zero-field offset ±300 µT (3σ) |
| soft_iron | symmetric, 1–3 % diagonal, 0.6–1 % off | AK8963 sensitivity 1.5 %, cross-axis 0.5 % (1σ, engineering) |
| frame_rotation | (1.0, −0.7, 1.5)° | die-to-die 0.5° (1σ, engineering) |
| room anomaly | a 3 cm steel sphere 8 cm from the board during a walk past | a chair leg, a desk frame |

Sessions (one deterministic truth each, reused with many sensor seeds):

* ``typical`` — the zhou2020 schedule, hand ``typical``, 100 Hz, with the simulation's truth rate;
* ``slow`` — the same rotations four times slower with the ``steady`` hand (peak angular
  acceleration 0.03 rad/s² from the schedule, 0.13 rad/s² RMS from tremor, vs 0.9 rad/s² for
  ``typical``), 100 Hz: a time offset or a nonlinearity has little to show itself with;
* ``walk_past`` — turns about z, x, y in place, a 15 cm step east past a 3 cm steel sphere, a turn
  there, the step back and more turns (51 s, hand ``typical``): the room anomaly case;
* ``chamber`` — a board fixed in a thermal chamber, −20 → 70 °C twice at 60 °C/h with 30 min soaks
  (7 h at 1 Hz), the ``consumer_thermal`` gyro, given as a measured record would be: t, gyro, acc,
  temperature, no truth (the static reference).

Cases (:data:`SUITE` the single effects, :data:`HARD_SUITE` the harder ones) state what must be
named (``expected``, every one, in any order, each with |θ̂ − θ| ≤ 4σ̂ over its identifiable
parameters), what must never be added (``forbidden``), or a family quantity of which one must be
named (``expected_quantity``).  :func:`run_suite` runs cases × seeds and returns a table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Callable, Sequence

import numpy as np

from gyrosim import effects as E
from gyrosim.chamber import profile_from_dict, simulate_chamber
from gyrosim.magnetic import environment_from_text
from gyrosim.recording import Recording
from gyrosim.schedule import load_schedule, schedule_from_dict
from gyrosim.sensor_model import SensorModel, load_sensor
from gyrosim.thermal import ThermalModel
from gyrosim.units import G0

from calib.closeloop.candidates import Untestable
from calib.closeloop.catalogue import family_for
from calib.closeloop.loop import DEFAULT_DECLARED, CloseloopResult, run_closeloop
from calib.closeloop.mag.terms import MAG_TERMS, mag_term

__all__ = [
    "SUITE",
    "HARD_SUITE",
    "MAG_SUITE",
    "BASE_SENSOR",
    "WARM_UP",
    "SuiteCase",
    "CaseResult",
    "SuiteRow",
    "sensor_with",
    "run_case",
    "run_suite",
    "suite_truth",
    "format_suite",
]

D = math.pi / 180.0
MG = 1e-3 * G0
BASE_SENSOR = "zhou2020_sim_consumer"
WARM_UP = ThermalModel(ambient_c=25.0, self_heating_c=8.0, self_heating_tau_s=120.0, case_tau_s=30.0)
CHAMBER_PROFILE = {"start_c": -20.0, "repeat": 2,
                   "step": [{"hold_s": 1800.0}, {"ramp_to_c": 70.0, "rate_c_per_h": 60.0}, {"hold_s": 1800.0},
                            {"ramp_to_c": -20.0, "rate_c_per_h": 60.0}]}
ACC_THERMAL_DRIFT = E.TemperatureBias(coefficients=np.array([[0.8], [-1.2], [1.5]]) * MG, t_ref_c=25.0,
                                      range_c=(-45.0, 90.0))


@dataclass(frozen=True)
class SuiteCase:
    """Undeclared effects injected on a session, and what the loop must (not) name."""

    effects: tuple[E.Effect, ...] = ()
    thermal: ThermalModel | None = None
    session: str = "typical"
    accelerometer: tuple[E.Effect, ...] = ()
    base: str = BASE_SENSOR
    forbidden: tuple[str, ...] = ()            # kinds that must never be added
    expected_quantity: str | None = None       # a family quantity of which one kind must be named
    description: str = ""
    magnetometer: tuple[E.Effect, ...] = ()    # undeclared magnetometer effects (on the calibrated AK8963)
    mag: bool = False                          # a magnetometer case (the 9-axis device)
    expect_disturbance: bool = False           # a local anomaly must be reported as unexplained structure
    # kinds that, with the declared model, are the same answer as an injected one (scored against its truth by their
    # family): the general misalignment's antisymmetric half is the gyro's rotation against the accelerometer, its
    # symmetric half the declared non-orthogonality
    equivalent: tuple[tuple[str, str], ...] = ()

    def answers(self, kind: str) -> tuple[str, ...]:
        """``kind`` and the kinds equivalent to it (:attr:`equivalent`)."""
        return (kind,) + tuple(b for a, b in self.equivalent if a == kind)

    @property
    def effect(self) -> E.Effect:
        """The first injected effect (the single-effect cases have one)."""
        return self.effects[0]

    @property
    def expected(self) -> tuple[str, ...]:
        return () if self.expected_quantity else tuple(e.kind for e in self.effects + self.magnetometer)


def _single(effect: E.Effect, thermal: ThermalModel | None = None) -> SuiteCase:
    return SuiteCase((effect,), thermal, description=effect.kind)


SUITE: dict[str, SuiteCase] = {
    "time_offset": _single(E.TimeOffset(delay_s=0.0034)),
    "g_sensitivity": _single(E.GSensitivity(value=np.diag([0.10, 0.08, 0.12]) * D / G0)),
    "scale_nonlinearity": _single(E.ScaleNonlinearity(value=[2.0e-3, -1.5e-3, 2.5e-3])),
    "scale_asymmetry": _single(E.ScaleAsymmetry(value=[1.5e-3, -1.0e-3, 2.0e-3])),
    "misalignment": SuiteCase((E.Misalignment(value=[0.005, -0.003, 0.004, 0.002, -0.006, 0.003]),),
                              description="misalignment", equivalent=(("misalignment", "gyro_acc_misalignment"),)),
    "temperature_bias": _single(E.TemperatureBias(coefficients=np.array([[0.03], [-0.02], [0.025]]) * D), WARM_UP),
    "temperature_scale": _single(E.TemperatureScale(coefficients=np.array([[3e-4], [-2e-4], [2.5e-4]])), WARM_UP),
    "random_walk": _single(E.RandomWalk(value=np.full(3, 0.005 * D))),
    "magnetic_sensitivity": _single(E.MagneticSensitivity(value=np.diag([1.0, -1.0, 1.2]) * 6e-4 * D)),
}

HARD_SUITE: dict[str, SuiteCase] = {
    "temperature_bias+g_sensitivity": SuiteCase(
        (SUITE["temperature_bias"].effect, SUITE["g_sensitivity"].effect), WARM_UP,
        description="pair: temperature bias (8 °C warm-up) + g-sensitivity"),
    "time_offset+scale_nonlinearity": SuiteCase(
        (SUITE["time_offset"].effect, SUITE["scale_nonlinearity"].effect),
        description="pair: time offset + scale nonlinearity"),
    "misalignment+random_walk": SuiteCase(
        (SUITE["misalignment"].effect, SUITE["random_walk"].effect),
        description="pair: misalignment + bias drift", equivalent=SUITE["misalignment"].equivalent),
    "chamber_acc_drift": SuiteCase(
        (), session="chamber", base="consumer_thermal", accelerometer=(ACC_THERMAL_DRIFT,),
        forbidden=("g_sensitivity",), expected_quantity="temperature",
        description="static chamber −20…70 °C, gyro thermal drift + accelerometer 0.8–1.5 mg/°C, no truth"),
    "slow_time_offset": SuiteCase((SUITE["time_offset"].effect,), session="slow",
                                  description="slow motion (steady hand): time offset 3.4 ms"),
    "slow_scale_nonlinearity": SuiteCase((SUITE["scale_nonlinearity"].effect,), session="slow",
                                         description="slow motion (steady hand): scale nonlinearity"),
}

NEGATIVE = SuiteCase((), description="nothing undeclared (negative control)")

MAG_BASE = "mpu9250_9axis"
ROOM_ANOMALY = ("0.41,0.30,1.15,0.03",)   # a 3 cm steel sphere next to the walk-past spot (x, y, z, radius m)
MAG_SUITE: dict[str, SuiteCase] = {
    "hard_iron": SuiteCase(magnetometer=(E.HardIron(value=[40.0, -25.0, 60.0]),), mag=True,
                           forbidden=("soft_iron", "frame_rotation"), description="magnetometer: hard iron"),
    "soft_iron": SuiteCase(magnetometer=(E.SoftIron(matrix=[[1.03, 0.01, -0.008], [0.01, 0.975, 0.006],
                                                           [-0.008, 0.006, 1.01]]),), mag=True,
                           forbidden=("hard_iron", "frame_rotation"), description="magnetometer: soft iron"),
    "frame_rotation": SuiteCase(magnetometer=(E.FrameRotation(angles=np.radians([1.0, -0.7, 1.5])),), mag=True,
                                forbidden=("hard_iron", "soft_iron"),
                                description="magnetometer: misalignment to the IMU frame"),
    "room_anomaly": SuiteCase(session="walk_past", mag=True, expect_disturbance=True,
                              forbidden=tuple(MAG_TERMS),
                              description="magnetometer: a steel sphere in the room (walk past), nothing else"),
    "mag_negative": SuiteCase(mag=True, description="magnetometer: nothing undeclared (negative control)"),
}

WALK_PAST = {"name": "walk_past", "description": "turns in place, a step east past a steel object, back, more turns",
             "segments": [{"kind": "rest", "duration_s": 3.0}] + [
                 {"kind": "rotate", "axis": a, "angle_deg": 360.0, "duration_s": 7.0} for a in "zxy"] + [
                 {"kind": "translate", "displacement_m": [0.15, 0.0, 0.0], "duration_s": 2.0},
                 {"kind": "rotate", "axis": "z", "angle_deg": 360.0, "duration_s": 6.0},
                 {"kind": "translate", "displacement_m": [-0.15, 0.0, 0.0], "duration_s": 2.0}] + [
                 {"kind": "rotate", "axis": a, "angle_deg": -360.0, "duration_s": 7.0} for a in "xy"] + [
                 {"kind": "rest", "duration_s": 3.0}]}


def _slow_schedule():
    """zhou2020's rotations four times slower (each 2π turn in 36 s, switches in 18 s)."""
    base = load_schedule("zhou2020")
    segs = []
    for s in base.segments:
        d = {
            "kind": s.kind,
            "duration_s": s.duration_s * (2.0 if s.kind == "rest" else 4.0 if s.kind == "rotate" else 2.0),
        }
        if s.axis_body is not None:
            d["axis"] = [float(v) for v in s.axis_body]
            d["angle_deg"] = math.degrees(s.angle_rad)
        segs.append(d)
    return schedule_from_dict(
        {
            "name": "zhou2020_slow",
            "description": "zhou2020 rotations at a quarter of the rate",
            "initial_quat": [float(v) for v in base.initial_quat_nb],
            "segments": segs,
        },
        "zhou2020_slow",
    )


@lru_cache(maxsize=4)
def suite_truth(session: str, truth_seed: int = 1, hand: str | None = None) -> Recording:
    """The deterministic truth recording of a session (cached; read-only arrays)."""
    from gyrosim.simulate import simulate_truth

    rng = np.random.default_rng(truth_seed)
    if session == "typical":
        return simulate_truth("zhou2020", hand or "typical", 100.0, rng=rng)
    if session == "slow":
        return simulate_truth(_slow_schedule(), hand or "steady", 100.0, rng=rng)
    if session == "walk_past":
        return simulate_truth(schedule_from_dict(WALK_PAST, "walk_past"), hand or "typical", 100.0, rng=rng,
                              magnetic=environment_from_text(anomalies=ROOM_ANOMALY))
    raise KeyError(f"unknown suite session {session!r}: typical, slow or chamber")


def sensor_with(case: SuiteCase | None, base: str = BASE_SENSOR) -> SensorModel:
    """The base device plus the case's effects (and thermal model, accelerometer effects)."""
    s = load_sensor(case.base if case is not None else base)
    if case is None:
        return s
    mag = s.magnetometer
    if case.mag:   # the AK8963 as a calibrated compass: noise, quantisation and range only, plus the case's effects
        mag = tuple(e for e in load_sensor(MAG_BASE).magnetometer
                    if e.is_white_noise or isinstance(e, (E.Quantization, E.Saturation))) + tuple(case.magnetometer)
    return replace(s, gyro=s.gyro + tuple(case.effects), accelerometer=s.accelerometer + tuple(case.accelerometer),
                   thermal=case.thermal or s.thermal, magnetometer=mag)


def _recording(case: SuiteCase, truth: Recording | None, seed: int) -> Recording:
    from gyrosim.simulate import apply_sensor

    sensor = sensor_with(case)
    if case.session == "chamber":
        rec = simulate_chamber(profile_from_dict(CHAMBER_PROFILE, "suite_chamber"), sensor, 1.0, seed=seed)
        return Recording(t_s=rec.t_s, gyro_rad_s=rec.gyro_rad_s, acc_m_s2=rec.acc_m_s2, temp_c=rec.temp_c,
                         meta={"source": "suite chamber (measured channels only)", "seed": seed})
    return apply_sensor(truth, sensor, np.random.default_rng(seed))


@dataclass(frozen=True)
class CaseResult:
    """One suite case on one seed: what the loop added against what it was expected to name, the
    estimates' worst error in σ, and the held-out residual RMS of the declared, the loop's and the correct
    model (°/s; µT, the field residual, in a magnetometer case)."""

    case: str
    found: list[str]                 # in the order the loop added them
    expected: tuple[str, ...]
    named_first: bool                # the first addition is an expected kind (or of the expected quantity)
    named_all: bool                  # every expected kind named (any order), or one of the expected quantity
    forbidden_added: list[str]
    z_max: float                     # max |θ̂ − θ| / σ̂ over the expected effects' identifiable parameters
    error_declared: float            # held-out residual RMS, °/s
    error_loop: float
    error_correct: float             # the declared model + the true kinds, fitted the same way (NaN: none)
    result: CloseloopResult
    estimate: np.ndarray = field(default_factory=lambda: np.zeros(0))
    truth: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def effect(self) -> str:
        return self.case

    @property
    def ratio_to_correct(self) -> float:
        return self.error_loop / self.error_correct


def _case(name: str) -> SuiteCase:
    if name in SUITE:
        return SUITE[name]
    if name in HARD_SUITE:
        return HARD_SUITE[name]
    if name in MAG_SUITE:
        return MAG_SUITE[name]
    if name == "negative":
        return NEGATIVE
    raise KeyError(f"unknown suite case {name!r}; known: {', '.join([*SUITE, *HARD_SUITE, *MAG_SUITE, 'negative'])}")


def run_case(name: str, truth: Recording | None, seed: int, declared: tuple[str, ...] = DEFAULT_DECLARED, *,
             truth_seed: int = 1, hand: str = "typical") -> CaseResult:
    """Simulate one case (sensor noise from ``seed``) on ``truth`` (None: the case's own session, from
    ``truth_seed``; ``hand`` for the typical session) and run the loop."""
    case = _case(name)
    if truth is None and case.session != "chamber":
        truth = suite_truth(case.session, truth_seed, hand if case.session == "typical" else None)
    rec = _recording(case, truth, seed)
    res = run_closeloop(rec, declared)
    if case.mag:
        return _mag_case(name, case, rec, res)
    found = [f.effect for f in res.found]
    if case.expected_quantity:
        hits = [k for k in found if _quantity(k) == case.expected_quantity]
        named_all, named_first = bool(hits), bool(found) and _quantity(found[0]) == case.expected_quantity
    else:
        named_all = all(any(a in found for a in case.answers(k)) for k in case.expected)
        named_first = bool(found) and any(found[0] in case.answers(k) for k in case.expected) if case.expected \
            else not found
    forbidden = [k for k in found if k in case.forbidden]
    est, tru, sig = [], [], []
    device = {e.kind: e for e in sensor_with(case).gyro}
    for eff in case.effects:
        f = next((x for x in res.found if x.effect in case.answers(eff.kind)), None)
        fam = family_for(f.effect) if f is not None else None
        if f is None or isinstance(fam, Untestable):
            continue
        e_, t_, s_ = fam.compare_with_truth(f.effect, f.params, res.declared_params, eff, device)
        est.append(e_), tru.append(t_), sig.append(s_)
    if est:
        est_a, tru_a, sig_a = np.concatenate(est), np.concatenate(tru), np.concatenate(sig)
        z = float(np.max(np.abs(est_a - tru_a) / sig_a)) if named_all else math.inf
    else:
        est_a = tru_a = sig_a = np.zeros(0)
        z = math.inf if case.expected else math.nan
    err_correct = math.nan
    if case.expected and case.session != "chamber":
        correct = run_closeloop(rec, tuple(declared) + case.expected, candidates=[])
        err_correct = correct.error_before["held_out_residual_rms"]
    return CaseResult(name, found, case.expected, bool(named_first), bool(named_all), forbidden, z,
                      res.error_before["held_out_residual_rms"], res.error_after["held_out_residual_rms"], err_correct,
                      res, est_a, tru_a, sig_a)


def _mag_case(name: str, case: SuiteCase, rec: Recording, res: CloseloopResult) -> CaseResult:
    """A magnetometer case: named = the magnetometer loop's first (every) addition is the injected
    kind; the room anomaly is named when a disturbance is reported and no magnetometer term added;
    errors are the magnetometer's held-out field residual (µT)."""
    from calib.closeloop.mag.loop import run_mag_loop

    mag = res.magnetometer
    mfound = mag.found_kinds
    found = [f.effect for f in res.found] + mfound
    if case.expect_disturbance:
        named_all = named_first = bool(mag.disturbances) and not mfound
    else:
        named_all = all(k in mfound for k in case.expected)
        named_first = (bool(mfound) and mfound[0] in case.expected) if case.expected else not found
    est, tru, sig = [], [], []
    for eff in case.magnetometer:
        f = next((x for x in mag.found if x.effect == eff.kind), None)
        if f is None:
            continue
        est.append([v["value"] for v in f.params.values()]), sig.append([v["sigma"] for v in f.params.values()])
        tru.append(mag_term(eff.kind).truth_params(eff))
    if est:
        est_a, tru_a, sig_a = (np.concatenate([np.asarray(x, float) for x in a]) for a in (est, tru, sig))
        z = float(np.max(np.abs(est_a - tru_a) / sig_a)) if named_all else math.inf
    else:
        est_a = tru_a = sig_a = np.zeros(0)
        z = math.inf if case.expected else math.nan
    err_correct = math.nan
    if case.expected:
        err_correct = run_mag_loop(rec, case.expected, candidates=[]).error_before["held_out_field_residual_rms"]
    key = "held_out_field_residual_rms"
    return CaseResult(
        name,
        found,
        case.expected,
        bool(named_first),
        bool(named_all),
        [k for k in found if k in case.forbidden],
        z,
        mag.error_before.get(key, math.nan),
        mag.error_after.get(key, mag.error_before.get(key, math.nan)),
        err_correct,
        res,
        est_a,
        tru_a,
        sig_a,
    )


def _quantity(kind: str) -> str:
    fam = family_for(kind)
    return "" if isinstance(fam, Untestable) else fam.quantity


@dataclass(frozen=True)
class SuiteRow:
    """One case over seeds: counts and the worst estimate."""

    case: str
    description: str
    seeds: int
    named_all: int
    named_first: int
    forbidden_added: int
    added_anything: int
    z_max: float
    error_declared: float
    error_loop: float
    ratio_to_correct: float
    found: list[list[str]]


def run_suite(cases: Sequence[str], seeds: Sequence[int], progress: Callable[[str], None] | None = None, *,
              truth_seed: int = 1, hand: str = "typical") -> list[SuiteRow]:
    """Every case over every seed (one truth per session, reused)."""
    rows = []
    for name in cases:
        case = _case(name)
        res = []
        for s in seeds:
            if progress:
                progress(f"{name} seed {s}")
            res.append(run_case(name, None, s, truth_seed=truth_seed, hand=hand))
        z = [r.z_max for r in res if math.isfinite(r.z_max)]
        ratios = [r.ratio_to_correct for r in res if math.isfinite(r.error_correct)]
        rows.append(
            SuiteRow(
                name,
                case.description,
                len(res),
                sum(r.named_all for r in res),
                sum(r.named_first for r in res),
                sum(bool(r.forbidden_added) for r in res),
                sum(bool(r.found) for r in res),
                max(z) if z else math.nan,
                float(np.mean([r.error_declared for r in res])),
                float(np.mean([r.error_loop for r in res])),
                max(ratios) if ratios else math.nan,
                [r.found for r in res],
            )
        )
    return rows


def format_suite(rows: Sequence[SuiteRow]) -> str:
    """The suite table as printed by ``calib closeloop-suite`` (markdown)."""
    out = ["| case | named (all expected) | named first | forbidden added | added anything | max |θ̂ − θ|/σ̂ | "
           "held-out °/s: declared → loop | loop / correct |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        case = _case(r.case)
        if case.mag:
            out.append(_mag_row(r, case))
            continue
        if not (case.expected or case.expected_quantity):   # the negative control: nothing to name
            out.append(f"| {r.case} | — | — | — | {r.added_anything}/{r.seeds} | — | {r.error_declared:.4f} → "
                       f"{r.error_loop:.4f} | — |")
            continue
        out.append(
            f"| {r.case} | {r.named_all}/{r.seeds} | {r.named_first}/{r.seeds} | {r.forbidden_added}/{r.seeds} | "
            f"{r.added_anything}/{r.seeds} | {r.z_max:.2f} | {r.error_declared:.4f} → {r.error_loop:.4f} | "
            f"{r.ratio_to_correct:.3f} |"
        )
    return "\n".join(out)


def _mag_row(r: SuiteRow, case: SuiteCase) -> str:
    """A magnetometer case's row (errors: held-out field residual, µT; the anomaly is "named" when
    reported as a disturbance with no magnetometer term added)."""
    err = f"{r.error_declared:.3f} → {r.error_loop:.3f} µT"
    if not (case.expected or case.expect_disturbance):
        return f"| {r.case} | — | — | — | {r.added_anything}/{r.seeds} | — | {err} | — |"
    named = f"{r.named_all}/{r.seeds}" + (" (as a disturbance)" if case.expect_disturbance else "")
    z = f"{r.z_max:.2f}" if math.isfinite(r.z_max) else "—"
    ratio = f"{r.ratio_to_correct:.3f}" if math.isfinite(r.ratio_to_correct) else "—"
    return (f"| {r.case} | {named} | {r.named_first}/{r.seeds} | {r.forbidden_added}/{r.seeds} | "
            f"{r.added_anything}/{r.seeds} | {z} | {err} | {ratio} |")
