"""Orientation estimators behind the :mod:`gyrosim.orientation` interface.

Each adapter maps a recording (gyro rad/s, accelerometer m/s², magnetometer µT; body frame
Right-Forward-Up) to one quaternion per sample, (w, x, y, z), body → East-North-Up.  Every
package has its own conventions; each adapter states them and converts (``tests/orientation/test_orientation.py``
checks every adapter on a tilted, turned board from the independent generator):

| name | package | output of the package | conversion to body → ENU |
|---|---|---|---|
| ``vqf`` / ``vqf_9d`` | ``vqf`` (Laidig & Seel 2023) | ``quat6D``/``quat9D``: sensor → ENU, w first | none |
| ``madgwick`` / ``_9d`` | ours, compiled | body → NWU (x along the field) | q_z(+90°) ⊗ q |
| ``mahony`` / ``_9d`` | ours, compiled | body → NWU | q_z(+90°) ⊗ q |
| ``fusion`` / ``_9d`` | ``imufusion`` (x-io Fusion), ``CONVENTION_ENU`` | body → ENU, w first | units only (°/s, g) |
| ``madgwick_ahrs`` | ``ahrs`` 0.4 ``Madgwick`` (6-axis) | body → earth z up | q_z(+90°) ⊗ q |
| ``mahony_ahrs`` | ``ahrs`` 0.4 ``Mahony`` (6-axis) | body → earth z up | q_z(+90°) ⊗ q |

Ours are compiled in :mod:`calib.orientation.kernels`; ``madgwick_ahrs`` and ``mahony_ahrs`` are the
peers for ``madgwick`` and ``mahony``.

Gains: Madgwick β = 0.12 and Mahony k_P = 0.74, k_I = 0.0012 are the BROAD benchmark's TAGP
values, the one setting that minimises the mean total error over its 39 trials (Laidig et al.
2021, Data 6(7):72, example_code/out/results_*_average_rmse.json): tuned on real hand-held-class
motion, not on our simulator.  VQF runs with its package defaults (the paper's tuned values);
Fusion with the settings its README recommends (gain 0.5, acceleration and magnetic rejection
10°, recovery after 5 s, gyroscope range 2000 °/s) and its gyroscope bias (offset) corrector.

Madgwick and Mahony start from the first sample (tilt from the accelerometer; 9-axis the heading
of the field, TRIAD), as BROAD's example code does; VQF and Fusion start as their packages do.
The packages are an optional extra (``pip install 'gyrosim-calib[orientation]'``); nothing here
imports them before an estimator runs.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from gyrosim.units import RAD2DEG

from calib.orientation.kernels import madgwick as _madgwick_kernel
from calib.orientation.kernels import mahony as _mahony_kernel

__all__ = ["builtin", "Madgwick", "Mahony", "VQF", "Fusion", "MadgwickAhrs", "MahonyAhrs", "MadgwickParams",
           "MahonyParams", "FusionParams", "initial_quat_nwu", "NWU_TO_ENU"]

# q_z(+90°): the earth frame North-West-Up turned into East-North-Up (NWU's x, north, is ENU's y)
NWU_TO_ENU = np.array([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)])
G0_M_S2 = 9.80665
EXTRA = "pip install 'gyrosim-calib[orientation]'"


def _require(module: str, name: str):
    try:
        return importlib.import_module(module)
    except ImportError as exc:  # gyrosim.orientation turns this into MissingExtraError
        raise ImportError(f"orientation estimator {name!r} needs the package {module!r}, which is not installed: "
                          f"{EXTRA}") from exc


def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q, p (4,), q (N, 4)."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw], axis=1)


def _quat_from_matrix(r: np.ndarray) -> np.ndarray:
    """The unit quaternion of a rotation matrix (Shepperd's method: the largest of 4w², 4x², ... first)."""
    tr = np.trace(r)
    cands = np.array([tr, r[0, 0], r[1, 1], r[2, 2]])
    i = int(np.argmax(cands))
    if i == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif i == 1:
        s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [(r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif i == 2:
        s = 2.0 * math.sqrt(1.0 - r[0, 0] + r[1, 1] - r[2, 2])
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 - r[0, 0] - r[1, 1] + r[2, 2])
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q) * (1.0 if q[0] >= 0 else -1.0)


def initial_quat_nwu(acc: np.ndarray, mag: np.ndarray | None = None) -> np.ndarray:
    """Body → North-West-Up from one sample.  The earth axes seen in the body frame are the rows
    of R (body → earth): up ẑ = f/‖f‖ (at rest the specific force points up); with a field m,
    north x̂ = (m − (m·ẑ) ẑ)/‖·‖ (its horizontal part), west ŷ = ẑ × x̂ (TRIAD).  Without a field,
    the shortest rotation taking ẑ to +z (heading zero)."""
    z = np.asarray(acc, dtype=float) / np.linalg.norm(acc)
    if mag is None:
        w = 1.0 + z[2]
        if w < 1e-9:  # upside down: a half turn about x
            return np.array([0.0, 1.0, 0.0, 0.0])
        # rotation taking body vector z to earth (0, 0, 1): axis z × e_z = (z_y, −z_x, 0)
        q = np.array([w, z[1], -z[0], 0.0])
        return q / np.linalg.norm(q)
    m = np.asarray(mag, dtype=float)
    x = m - (m @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return _quat_from_matrix(np.vstack([x, y, z]))


def _to_enu(q_nwu: np.ndarray) -> np.ndarray:
    return _qmul(NWU_TO_ENU, q_nwu)


def _inputs(rec, magnetometer: bool, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, float]:
    gyr = np.ascontiguousarray(rec.gyro_rad_s, dtype=float)
    acc = np.ascontiguousarray(rec.acc_m_s2, dtype=float)
    mag = None
    if magnetometer:
        if rec.mag_ut is None:
            raise ValueError(f"{name} is a 9-axis estimator but the recording has no magnetometer (/mag); use the "
                             "6-axis variant or a sensor with a magnetometer (e.g. mpu9250_9axis)")
        mag = np.ascontiguousarray(rec.mag_ut, dtype=float)
    dt = np.diff(rec.t_s)
    if dt.size and np.max(np.abs(dt - np.median(dt))) > 0.01 * np.median(dt):
        raise ValueError(f"{name} needs a uniform sample clock; Δt varies from {dt.min():.6g} to {dt.max():.6g} s "
                         "(resample first)")
    return gyr, acc, mag, float(np.median(dt))


def _result(q: np.ndarray, name: str, magnetometer: bool, **diag: Any) -> dict:
    return {"quat_nb": q, "method": name, "magnetometer": magnetometer, "diagnostics": diag}


@dataclass(frozen=True)
class MadgwickParams:
    """β (rad/s): the gradient step, Madgwick 2011 eq. 33; 0.12 = BROAD's TAGP (module docstring).
    ``field_reference``: ``"paper"`` (b = (‖h_xy‖, 0, h_z), eqs. 45–46) or ``"c2011"``, the half-size
    reference of Madgwick's 2011 C code (:func:`calib.orientation.kernels.madgwick`), for comparing
    with results computed with that code (BROAD's)."""

    beta: float = 0.12
    field_reference: str = "paper"


@dataclass(frozen=True)
class MahonyParams:
    """k_P (rad/s per unit error) and k_I (rad/s² per unit error), Mahony 2008 eq. 48; BROAD TAGP."""

    k_p: float = 0.74
    k_i: float = 0.0012


@dataclass(frozen=True)
class FusionParams:
    """x-io Fusion's AHRS settings as its README recommends (angles in °, times in s)."""

    gain: float = 0.5
    gyroscope_range_deg_s: float = 2000.0
    acceleration_rejection_deg: float = 10.0
    magnetic_rejection_deg: float = 10.0
    recovery_trigger_period_s: float = 5.0
    bias_correction: bool = True


class Madgwick:
    """Madgwick's gradient-descent filter (compiled kernel, :func:`calib.orientation.kernels.madgwick`)."""

    def __init__(self, params: MadgwickParams = MadgwickParams(), magnetometer: bool = False) -> None:
        self.params, self.magnetometer = params, magnetometer
        self.name = "madgwick_9d" if magnetometer else "madgwick"

    def __call__(self, rec) -> dict:
        gyr, acc, mag, dt = _inputs(rec, self.magnetometer, self.name)
        q0 = initial_quat_nwu(acc[0], None if mag is None else mag[0])
        if self.params.field_reference not in ("paper", "c2011"):
            raise ValueError(f"field_reference must be 'paper' or 'c2011', got {self.params.field_reference!r}")
        scale = 0.5 if self.params.field_reference == "c2011" else 1.0
        q = _madgwick_kernel(gyr, acc, mag if mag is not None else np.zeros((0, 3)), dt, self.params.beta, q0, scale)
        return _result(_to_enu(q), self.name, self.magnetometer)


class Mahony:
    """Mahony's explicit complementary filter with gyro-bias integral (compiled kernel)."""

    def __init__(self, params: MahonyParams = MahonyParams(), magnetometer: bool = False) -> None:
        self.params, self.magnetometer = params, magnetometer
        self.name = "mahony_9d" if magnetometer else "mahony"

    def __call__(self, rec) -> dict:
        gyr, acc, mag, dt = _inputs(rec, self.magnetometer, self.name)
        q0 = initial_quat_nwu(acc[0], None if mag is None else mag[0])
        q, b = _mahony_kernel(gyr, acc, mag if mag is not None else np.zeros((0, 3)), dt, self.params.k_p,
                              self.params.k_i, q0, np.zeros(3))
        return _result(_to_enu(q), self.name, self.magnetometer, final_bias_rad_s=b.tolist())


class VQF:
    """VQF (Laidig & Seel 2023), the package's C++ implementation with its default parameters:
    rest detection, gyro bias estimation at rest and in motion, magnetic disturbance rejection."""

    def __init__(self, magnetometer: bool = False, **params: Any) -> None:
        self.magnetometer, self.params = magnetometer, params
        self.name = "vqf_9d" if magnetometer else "vqf"

    def __call__(self, rec) -> dict:
        vqf = _require("vqf", self.name)
        gyr, acc, mag, dt = _inputs(rec, self.magnetometer, self.name)
        f = vqf.VQF(dt, **self.params)
        out = f.updateBatch(gyr, acc, mag) if mag is not None else f.updateBatch(gyr, acc)
        q = out["quat9D"] if mag is not None else out["quat6D"]
        return _result(np.asarray(q, dtype=float), self.name, self.magnetometer,
                       final_bias_rad_s=np.asarray(out["bias"][-1]).tolist(),
                       rest_fraction=float(np.mean(out["restDetected"])))


class Fusion:
    """x-io Fusion (``imufusion``): a Mahony-type complementary filter with acceleration and
    magnetic rejection, and its stationary gyro-offset corrector."""

    def __init__(self, params: FusionParams = FusionParams(), magnetometer: bool = False) -> None:
        self.params, self.magnetometer = params, magnetometer
        self.name = "fusion_9d" if magnetometer else "fusion"

    def __call__(self, rec) -> dict:
        fu = _require("imufusion", self.name)
        gyr, acc, mag, dt = _inputs(rec, self.magnetometer, self.name)
        rate = 1.0 / dt
        p = self.params
        ahrs = fu.Ahrs()
        # imufusion 1.3.3's AhrsSettings(...) constructor ignores its ``convention`` keyword (it
        # stays NWU: measured, the 9-axis heading came out 90° off); each field is set through its
        # property and read back, so a binding that drops one is an error, not a silent frame change.
        settings = fu.AhrsSettings()
        wanted = {"sample_rate": rate, "convention": fu.CONVENTION_ENU, "gain": p.gain,
                  "gyroscope_range": p.gyroscope_range_deg_s, "acceleration_rejection": p.acceleration_rejection_deg,
                  "magnetic_rejection": p.magnetic_rejection_deg,
                  # seconds in imufusion 1.3 (measured: the recovery trigger grows by Δt/timeout per
                  # rejected sample), where the C library's older recoveryTriggerPeriod counted samples
                  "rejection_timeout": p.recovery_trigger_period_s}
        for key, value in wanted.items():
            setattr(settings, key, value)
            if not math.isclose(float(getattr(settings, key)), float(value), rel_tol=1e-6):
                raise RuntimeError(f"imufusion did not take the setting {key} = {value} (reads "
                                   f"{getattr(settings, key)})")
        ahrs.set_settings(settings)
        ahrs.set_sample_period(dt)
        bias = None
        if p.bias_correction:
            bias = fu.Bias()
            bs = fu.BiasSettings()
            bs.sample_rate = rate
            bias.set_settings(bs)
        g_deg = np.ascontiguousarray(gyr * RAD2DEG)
        a_g = np.ascontiguousarray(acc / G0_M_S2)
        q = np.empty((rec.n, 4))
        for k in range(rec.n):
            g = bias.update(g_deg[k]) if bias is not None else g_deg[k]
            if mag is not None:
                ahrs.update(g, a_g[k], mag[k])
            else:
                ahrs.update_no_magnetometer(g, a_g[k])
            q[k] = ahrs.get_quaternion()
        diag = {"final_offset_deg_s": bias.get_offset().tolist()} if bias is not None else {}
        return _result(q, self.name, self.magnetometer, **diag)


class MadgwickAhrs:
    """The ``ahrs`` package's Madgwick (6-axis), started from the same first-sample attitude as
    ours: the peer our compiled kernel is checked against (slow: a Python loop per sample)."""

    name = "madgwick_ahrs"

    def __init__(self, params: MadgwickParams = MadgwickParams()) -> None:
        self.params = params

    def __call__(self, rec) -> dict:
        filters = _require("ahrs", self.name).filters
        gyr, acc, _, dt = _inputs(rec, False, self.name)
        q0 = initial_quat_nwu(acc[0])
        q = filters.Madgwick(gyr=gyr, acc=acc, frequency=1.0 / dt, gain=self.params.beta, q0=q0).Q
        return _result(_to_enu(q), self.name, False)


class MahonyAhrs:
    """The ``ahrs`` package's Mahony (6-axis), the peer for ``mahony``."""

    name = "mahony_ahrs"

    def __init__(self, params: MahonyParams = MahonyParams()) -> None:
        self.params = params

    def __call__(self, rec) -> dict:
        filters = _require("ahrs", self.name).filters
        gyr, acc, _, dt = _inputs(rec, False, self.name)
        q0 = initial_quat_nwu(acc[0])
        q = filters.Mahony(gyr=gyr, acc=acc, frequency=1.0 / dt, k_P=self.params.k_p, k_I=self.params.k_i, q0=q0).Q
        return _result(_to_enu(q), self.name, False)


_BUILTINS = {
    "vqf": lambda: VQF(), "vqf_9d": lambda: VQF(magnetometer=True),
    "madgwick": lambda: Madgwick(), "madgwick_9d": lambda: Madgwick(magnetometer=True),
    "mahony": lambda: Mahony(), "mahony_9d": lambda: Mahony(magnetometer=True),
    "fusion": lambda: Fusion(), "fusion_9d": lambda: Fusion(magnetometer=True),
    "madgwick_c2011_9d": lambda: Madgwick(MadgwickParams(field_reference="c2011"), magnetometer=True),
    "madgwick_ahrs": lambda: MadgwickAhrs(), "mahony_ahrs": lambda: MahonyAhrs(),
}
_PACKAGE = {"vqf": "vqf", "fusion": "imufusion", "ahrs": "ahrs"}


def builtin(name: str):
    """The built-in estimator ``name``; its optional package must be importable now (so a
    campaign refuses before any work, naming the extra)."""
    est = _BUILTINS[name]()
    for key, module in _PACKAGE.items():
        if name.startswith(key) or name.endswith(key):
            _require(module, name)
    return est


# the zero-argument factories registered in pyproject.toml (entry-point group
# gyrosim.orientation_estimators): gyrosim finds them by name without importing calib
vqf = partial(builtin, "vqf")
vqf_9d = partial(builtin, "vqf_9d")
madgwick = partial(builtin, "madgwick")
madgwick_9d = partial(builtin, "madgwick_9d")
mahony = partial(builtin, "mahony")
mahony_9d = partial(builtin, "mahony_9d")
fusion = partial(builtin, "fusion")
fusion_9d = partial(builtin, "fusion_9d")
madgwick_c2011_9d = partial(builtin, "madgwick_c2011_9d")
madgwick_ahrs = partial(builtin, "madgwick_ahrs")
mahony_ahrs = partial(builtin, "mahony_ahrs")

BUILTIN_NAMES = tuple(_BUILTINS)  # the names above, as registered
__all__ += ["BUILTIN_NAMES", *BUILTIN_NAMES]
