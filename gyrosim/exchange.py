"""Calibrations and sensor models in other tools' formats: Kalibr ``imu.yaml`` (out and in) and imucal's
JSON (out).

**Kalibr** (ethz-asl/kalibr, wiki "IMU Noise Model"): the IMU file holds the continuous-time noise of
each triad, the convention of :class:`gyrosim.effects.WhiteNoise` / :class:`gyrosim.effects.RandomWalk`:

* ``gyroscope_noise_density`` σ_g (rad/s/√Hz) and ``accelerometer_noise_density`` σ_a (m/s²/√Hz):
  white noise, per sample σ_d = σ √(update_rate) — our density N (IEEE 952 ARW/VRW), unchanged;
* ``gyroscope_random_walk`` σ_bg (rad/s²/√Hz) and ``accelerometer_random_walk`` σ_ba (m/s³/√Hz):
  the bias's Wiener process, per sample σ_bd = σ_b √Δt — our ``random_walk`` value K, unchanged;
* ``update_rate`` (Hz) and ``rostopic``.

A calibration carries the white-noise densities it measured at rest; the random walks a 3-minute
session cannot measure (they need an Allan deviation over hours, ``calib allan``).  Each of the four
numbers is taken, first found: from the caller's value for it (``calib export --gyro-random-walk`` …),
from ``noise`` (Kalibr's four keys as ``calib allan --json`` measured them on a long static record of
the same IMU, ``calib export --noise``), from the calibration's own ``white_noise`` / ``random_walk``
effects; a number none of them has is refused, saying where to get it.
Kalibr's own advice is to inflate the values for real-world use; nothing is inflated here.  Kalibr's
imu.yaml has no place for scale factor or axis errors (its camera–IMU calibration estimates its own);
they are written as comments so the file stays one a Kalibr run accepts — with the gyro's rotation against the
accelerometer (``gyro_acc_misalignment`` α) in the form Kalibr's scale-misalignment model reports it, ``C_gyro_i``
(Rehder et al., "Extending Kalibr", ICRA 2016: ω_gyro = C_gyro_i ω_imu, the accelerometer's frame being the IMU's),
here R(α)ᵀ.

**imucal** (mad-lab-fau/imucal 2.x, ``FerrarisCalibrationInfo.to_json``): raw = K R x + b per triad
(K diagonal, R with unit-norm rows), gyro also + K_ga a, gyro in °/s.  Our axis matrix M (every linear term of
the triad: I + diag(S) + N(G), and the gyro's −[α×] when the calibration has its rotation against the
accelerometer) is written as K = diag(‖row_i(M)‖), R = K⁻¹ M; b_g in °/s; K_ga = 0 (not estimated).  imucal has
no term of its own for the gyro–accelerometer misalignment: its R_g is a general matrix, so the rotation is in it.
The file loads with ``imucal.management.load_calibration_info`` and ``calibrate()`` gives our compensation.

Both write a calibration as ``calib apply`` applies it (:meth:`gyrosim.calibration.Calibration.as_applied`): with
an ``applied`` block, the parameters the session determined and the prior's values for the rest — not the
estimate of a parameter the motion left undetermined.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .calibration import LINEAR_KINDS, Calibration
from .errors import GyrosimError, PresetError

__all__ = ["kalibr_imu_yaml", "sensor_from_kalibr", "imucal_json"]

_KALIBR_KEYS = ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                "gyroscope_random_walk")


def _density(cal: Calibration, triad: str, kind: str, field: str) -> float | None:
    e = cal.effect(triad, kind)
    if e is None:
        return None
    v = np.asarray(getattr(e, field), float)
    return float(np.mean(v)) if v.size else None


def kalibr_imu_yaml(cal: Calibration, update_rate_hz: float, *, rostopic: str = "/imu0",
                    gyro_random_walk: float | None = None, acc_random_walk: float | None = None,
                    noise: Mapping[str, float | None] | None = None) -> str:
    """Kalibr's ``imu.yaml`` for ``cal`` (module docstring; densities averaged over the three axes).
    ``noise``: Kalibr's four keys (SI, None for a number not measured), e.g. from ``calib allan --json``; the two
    random walks given as arguments win over it, and it wins over the calibration's own noise effects.  The
    intrinsics in its comments are what ``calib apply`` applies (:meth:`Calibration.as_applied`)."""
    if not (math.isfinite(update_rate_hz) and update_rate_hz > 0):
        raise GyrosimError(f"update rate must be a positive number of Hz, got {update_rate_hz}")
    cal = cal.as_applied()
    noise = dict(noise or {})
    given = {"gyroscope_random_walk": gyro_random_walk, "accelerometer_random_walk": acc_random_walk}
    own = {"gyroscope_noise_density": ("gyro", "white_noise", "density"),
           "accelerometer_noise_density": ("accelerometer", "white_noise", "density"),
           "gyroscope_random_walk": ("gyro", "random_walk", "value"),
           "accelerometer_random_walk": ("accelerometer", "random_walk", "value")}
    values: dict[str, float | None] = {}
    for key, where in own.items():
        picks = (given.get(key), noise.get(key), _density(cal, *where))
        values[key] = next((float(v) for v in picks if v is not None), None)
    gn, an = values["gyroscope_noise_density"], values["accelerometer_noise_density"]
    grw, arw = values["gyroscope_random_walk"], values["accelerometer_random_walk"]
    how = {"gyroscope_noise_density": "gyro white noise density (rad/s/√Hz)",
           "accelerometer_noise_density": "accelerometer white noise density (m/s²/√Hz)",
           "gyroscope_random_walk": "gyro random walk (rad/s²/√Hz; or --gyro-random-walk)",
           "accelerometer_random_walk": "accelerometer random walk (m/s³/√Hz; or --acc-random-walk)"}
    missing = [how[k] for k, v in values.items() if v is None]
    if missing:
        raise GyrosimError(
            f"a Kalibr imu.yaml needs the {', '.join(missing)}, which neither the calibration nor the noise file "
            "carries: a session of minutes cannot measure a bias random walk — measure it on a static recording of "
            "an hour or more (calib allan REC --json noise.json, then calib export --noise noise.json) or take it "
            "from the datasheet and pass it"
        )
    lines = [
        "# IMU noise model for Kalibr (https://github.com/ethz-asl/kalibr/wiki/IMU-Noise-Model)",
        "# continuous-time values: white noise density sigma (per sample sigma * sqrt(update_rate)),",
        "# bias random walk sigma_b (per sample sigma_b * sqrt(1/update_rate)); not inflated",
        f"# written by gyrosim/calib (method {cal.method or 'unknown'}, status {cal.status})",
        "",
        "#Accelerometers",
        f"accelerometer_noise_density: {an:.6e}   #Noise density (continuous-time), m/s^2/sqrt(Hz)",
        f"accelerometer_random_walk:   {arw:.6e}   #Bias random walk, m/s^3/sqrt(Hz)",
        "",
        "#Gyroscopes",
        f"gyroscope_noise_density:     {gn:.6e}   #Noise density (continuous-time), rad/s/sqrt(Hz)",
        f"gyroscope_random_walk:       {grw:.6e}   #Bias random walk, rad/s^2/sqrt(Hz)",
        "",
        f"rostopic:                    {rostopic}   #the IMU ROS topic",
        f"update_rate:                 {update_rate_hz:.6g}   #Hz (for discretization of the values above)",
        "",
        "# intrinsics as calib apply applies them (body frame RFU; raw = (I + diag(S) + N(G)) x + b), for reference:",
    ]
    for triad, unit in (("gyro", "rad/s"), ("accelerometer", "m/s^2")):
        for kind, label in (("bias", f"bias ({unit})"), ("scale_factor", "scale factor S"),
                            ("nonorthogonality", "non-orthogonality G")):
            if cal.has(triad, kind):
                lines.append(f"#   {triad} {label}: "
                             f"{np.array2string(cal.value(triad, kind), precision=6, separator=', ')}")
    rot = next((e for e in cal.gyro if e.axis_rotation and e.triads == ("gyro",) and e.params().size == 3), None)
    if rot is not None:   # the gyro's rotation against the accelerometer, Kalibr's C_gyro_i = R(α)ᵀ
        from .effects import rotation_matrix

        c = rotation_matrix(rot.params()).T
        lines.append(f"#   gyro rotation against the accelerometer alpha (rad, about x, y, z): "
                     f"{np.array2string(rot.params(), precision=6, separator=', ')}")
        lines.append("#   C_gyro_i (Kalibr scale-misalignment model, omega_gyro = C_gyro_i omega_imu, row-major): "
                     + np.array2string(c.ravel(), precision=8, separator=", ", max_line_width=400))
    return "\n".join(lines) + "\n"


def sensor_from_kalibr(path: str | Path):
    """A :class:`~gyrosim.sensor_model.SensorModel` from a Kalibr ``imu.yaml``: white noise and bias random
    walk of both triads (module docstring for the units); no deterministic errors (the file has none)."""
    import yaml

    from .effects import RandomWalk, WhiteNoise
    from .sensor_model import SensorModel

    path = Path(path)
    if not path.is_file():
        raise PresetError(f"no such Kalibr IMU file: {path}")
    try:
        data: Any = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise PresetError(f"{path}: not valid YAML ({exc})") from exc
    if not isinstance(data, dict):
        raise PresetError(f"{path}: a Kalibr imu.yaml is a mapping of keys, got {type(data).__name__}")
    missing = [k for k in _KALIBR_KEYS if k not in data]
    if missing:
        raise PresetError(f"{path}: missing Kalibr key(s) {missing}; an imu.yaml has {', '.join(_KALIBR_KEYS)}")
    vals = {}
    for k in _KALIBR_KEYS:
        try:
            v = float(data[k])
        except (TypeError, ValueError) as exc:
            raise PresetError(f"{path}: {k} = {data[k]!r} is not a number") from exc
        if not (math.isfinite(v) and v >= 0):
            raise PresetError(f"{path}: {k} = {v} must be a finite value ≥ 0")
        vals[k] = v
    note = f"Kalibr imu.yaml {path.name}" + (f", update_rate {data['update_rate']} Hz" if "update_rate" in data else "")
    return SensorModel(
        name=path.stem,
        gyro=(WhiteNoise(density=np.full(3, vals["gyroscope_noise_density"])),
              RandomWalk(value=np.full(3, vals["gyroscope_random_walk"]))),
        accelerometer=(WhiteNoise(density=np.full(3, vals["accelerometer_noise_density"])),
                       RandomWalk(value=np.full(3, vals["accelerometer_random_walk"]))),
        description="noise model read from a Kalibr imu.yaml (continuous-time densities and random walks)",
        source=str(path), notes={"kalibr": note})


def _k_r(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    k = np.diag(np.linalg.norm(m, axis=1))
    return k, np.linalg.inv(k) @ m


def imucal_json(cal: Calibration, comment: str = "") -> str:
    """imucal's Ferraris JSON layout for ``cal`` as ``calib apply`` applies it (:meth:`Calibration.as_applied`: the
    parameters the session determined, the prior's for the rest; module docstring); raises if a triad is missing."""
    from .effects import nonortho_matrix

    cal = cal.as_applied()

    for triad in ("gyro", "accelerometer"):
        if not any(cal.has(triad, k) for k in LINEAR_KINDS):
            raise GyrosimError(f"imucal's format needs both triads; this calibration has no {triad} intrinsics "
                               "(calibrate with --accelerometer estimate)")
    def m(triad: str) -> np.ndarray:   # I + diag(S) + N(G), and every other axis term (the gyro's −[α×])
        out = np.eye(3) + np.diag(cal.value(triad, "scale_factor"))
        out = out + nonortho_matrix(cal.value(triad, "nonorthogonality"))
        for e in getattr(cal, triad):
            if e.axis_rotation and not e.stochastic and e.affine() is not None:
                out = out + e.affine()[0]
        return out

    k_a, r_a = _k_r(m("accelerometer"))
    k_g, r_g = _k_r(m("gyro"))
    d = {"acc_unit": "m/s^2", "gyr_unit": "deg/s", "from_acc_unit": "m/s^2", "from_gyr_unit": "deg/s",
         "comment": comment or f"gyrosim/calib {cal.method} (status {cal.status}); body frame RFU; K_ga not estimated",
         "K_a": k_a.tolist(), "R_a": r_a.tolist(), "b_a": cal.value("accelerometer", "bias").tolist(),
         "K_g": k_g.tolist(), "R_g": r_g.tolist(), "K_ga": np.zeros((3, 3)).tolist(),
         "b_g": np.degrees(cal.value("gyro", "bias")).tolist(), "cal_type": "Ferraris", "_format_version": "2.0.0"}
    return json.dumps(d, indent=4)
