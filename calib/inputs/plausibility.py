"""Unit checks: is the accelerometer in m/s² and the gyro in rad/s (after the declared conversion)?

Accelerometer — the median |f| of a hand session or a static record is gravity:

| median |f|   | verdict                                   |
|--------------|-------------------------------------------|
| 7 – 13       | m/s² (accepted)                            |
| 0.5 – 2      | g read as m/s² → ``--acc-unit g``          |
| 70 – 130     | m/s² declared as g (×9.81 twice) → drop it |
| 500 – 2000   | mg → ``--acc-unit mg``                     |
| 5e5 – 2e6    | µg → ``--acc-unit ug``                     |
| else         | refused: not gravity in any unit          |

Gyro — three independent tests, any of which names deg/s read as rad/s:

* peak rate > 35 rad/s (2000 °/s, the largest MEMS full scale);
* rest level (the gyro where the accelerometer is calm, :mod:`calib.inputs.motion`) > 0.5 rad/s:
  a bias of 29 °/s is beyond any MEMS gyro, while 0.5 °/s read as rad/s gives exactly this;
* the gravity-consistency test of :mod:`calib.inputs.motion`, which also catches a slow session
  with a small bias (its rotation, integrated as rad/s, turns gravity 57× too far).
"""

from __future__ import annotations

import math

import numpy as np

from gyrosim.recording import Recording

from calib.inputs.motion import FACTORS, Consistency, MotionSummary

__all__ = ["MAX_PLAUSIBLE_RATE_RAD_S", "MAX_REST_LEVEL_RAD_S", "acc_unit_problem", "gyro_unit_problem"]

MAX_PLAUSIBLE_RATE_RAD_S = 35.0   # 2000 °/s: the largest MEMS full scale
MAX_REST_LEVEL_RAD_S = 0.5        # 29 °/s: no MEMS gyro has such a bias


def acc_unit_problem(rec: Recording) -> str | None:
    """Message when the accelerometer magnitude is not gravity in m/s² (table above)."""
    f = np.asarray(rec.acc_m_s2, dtype=float)
    f_med = float(np.median(np.sqrt(np.einsum("ij,ij->i", f, f))))
    declared = str(rec.meta.get("acc_unit", "m/s^2"))
    if 7.0 < f_med < 13.0:
        return None
    if 0.5 < f_med < 2.0:
        return (f"the accelerometer's median magnitude is {f_med:.3f}: that is gravity in g, not m/s²; "
                "pass --acc-unit g (acc_unit='g')")
    if 70.0 < f_med < 130.0 and declared.strip().lower() == "g":
        return (f"the accelerometer's median magnitude is {f_med:.1f} m/s² after the declared g → m/s² conversion: "
                "the values were already in m/s²; drop --acc-unit g")
    if 500.0 < f_med < 2000.0:
        return f"the accelerometer's median magnitude is {f_med:.0f}: that is gravity in mg; pass --acc-unit mg"
    if 5e5 < f_med < 2e6:
        return f"the accelerometer's median magnitude is {f_med:.3g}: that is gravity in µg; pass --acc-unit ug"
    return (f"the accelerometer's median magnitude is {f_med:.4g} m/s², far from gravity (9.81) in any unit: check "
            "--acc-unit and that the accelerometer channels are the ones named acc_x, acc_y, acc_z")


def gyro_unit_problem(rec: Recording, motion: MotionSummary | None = None,
                      consistency: Consistency | None = None) -> str | None:
    """Message when the gyro is not in rad/s after the declared conversion (module docstring)."""
    declared = str(rec.meta.get("gyro_unit", "rad/s"))
    as_rad = declared.strip().lower() in ("rad/s", "rad/sec")
    if motion is not None and motion.rest_level_rad_s is not None:
        level = float(np.linalg.norm(motion.rest_level_rad_s))
        if level > MAX_REST_LEVEL_RAD_S:
            return (
                f"the gyro reads {level:.2f} rad/s ({math.degrees(level):.0f} °/s) where the accelerometer says "
                "the board is still: no MEMS gyro has such a bias; the rates are probably in deg/s — pass "
                "--gyro-unit deg/s (gyro_unit='deg/s')"
                if as_rad
                else f"the gyro reads {level:.2f} rad/s ({math.degrees(level):.0f} °/s) after the declared {declared} "
                "conversion where the accelerometer says the board is still: check --gyro-unit and the gyro columns"
            )
    if consistency is not None:
        k = consistency.verdict()
        if k is not None:
            e1, ek = consistency.errors_deg[1.0], consistency.errors_deg[k]
            evidence = (
                f"integrated as declared, the gyro predicts the gravity direction the accelerometer sees "
                f"with a median error of {e1:.0f}° over {consistency.pairs} moves; {FACTORS[k]} fits ({ek:.1f}°)"
            )
            if k == math.pi / 180:
                return f"{evidence}: the rates are in deg/s; pass --gyro-unit deg/s (gyro_unit='deg/s')"
            if k == 180 / math.pi:
                return f"{evidence}: the rates are already in rad/s; drop --gyro-unit {declared}"
            if k == 1e-3:
                return f"{evidence}: the time column is in ms, not s; pass --time-unit ms"
            return f"{evidence}: the time column is 1000× too short; check --time-unit"
    g = np.asarray(rec.gyro_rad_s, dtype=float)
    rate = np.maximum(np.maximum(np.abs(g[:, 0]), np.abs(g[:, 1])), np.abs(g[:, 2]))
    peak = float(rate.max())
    if peak > MAX_PLAUSIBLE_RATE_RAD_S:
        over = rate > MAX_PLAUSIBLE_RATE_RAD_S
        if over.mean() < 0.005 and float(np.percentile(rate, 99)) < 0.5 * MAX_PLAUSIBLE_RATE_RAD_S:
            k = int(np.argmax(over))
            return (f"{int(over.sum())} gyro sample(s) exceed {MAX_PLAUSIBLE_RATE_RAD_S:g} rad/s (2000 °/s, beyond any "
                    f"MEMS range; up to {peak:.3g} rad/s, first at t = {rec.t_s[k]:.4f} s) while 99 % stay below "
                    f"{float(np.percentile(rate, 99)):.2f} rad/s: corrupt values, not a unit; cut them out")
        if as_rad:
            return (f"the gyro reaches {peak:.1f} rad/s ({np.degrees(peak):.0f} °/s), beyond any MEMS range: the "
                    "rates are probably in deg/s; pass --gyro-unit deg/s (gyro_unit='deg/s')")
        return (f"the gyro reaches {peak:.1f} rad/s ({np.degrees(peak):.0f} °/s) after the declared {declared} "
                "conversion, beyond any MEMS range: check --gyro-unit and the gyro columns")
    return None
