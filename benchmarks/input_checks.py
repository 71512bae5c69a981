"""What the input boundary (calib.inputs) adds to ``calib run``, measured as a ratio in one run.

    python benchmarks/input_checks.py [--repeats 5]

For a ~3-minute session (zhou2020, 171 s at 100 Hz, simulated; and BROAD 07, 184 s at 285.7 Hz,
measured, when ../shared/data is there), each repeat times, interleaved:

* read — the file read and parsed (CSV or HDF5): needed with or without checks;
* boundary — ``calib.inputs.prepare_recording`` (time base, degenerate data, spikes, gaps, units,
  motion, rate: everything ``calib run`` checks before the filter);
* re-check — ``calib.inputs.check_recording`` as ``prepare()`` runs it inside ``calibrate``;
* calibrate — ``calib.session.paper.calibrate(rec)`` (``kf_joint``) (the filter; includes the re-check), as
  ``calib run`` runs it (accelerometer estimated; BROAD with ``--accelerometer calibrated``, as its
  motion cannot separate the accelerometer).

overhead = (boundary + re-check) / (read + calibrate − re-check): all checking counted, even the
gap/unit/saturation checks the code made before the input boundary.  Times are the process's CPU time
(``time.process_time``, all threads), medians over the repeats: on the shared 2-core machine a
10 ms step measured by the wall clock mostly measures the scheduler (a 1 ms check read 1–60 ms at
load 10).  The wall-clock ratio is printed too, for reference.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def _time(fn):
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn()
    return (time.process_time() - c0, time.perf_counter() - w0), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    from gyrosim.loaders import available_datasets
    from gyrosim.recording import save_hdf5
    from gyrosim.simulate import simulate

    from calib.inputs import KF, check_recording, prepare_recording, read_recording
    from calib.session.paper import calibrate

    folder = Path(tempfile.mkdtemp())
    rec = simulate("zhou2020", "typical", "zhou2020_sim_consumer", 100.0, seed=1)
    h5 = save_hdf5(rec, folder / "session.h5")
    csv = folder / "session.csv"
    data = np.column_stack([rec.t_s, rec.gyro_rad_s, rec.acc_m_s2])
    csv.write_text(
        "t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z\n" + "\n".join(",".join(f"{v:.17g}" for v in r) for r in data) + "\n"
    )
    cases = [
        ("zhou2020 typical 100 Hz, HDF5", str(h5), "estimate"),
        ("zhou2020 typical 100 Hz, CSV", str(csv), "estimate"),
    ]
    if "broad/07_undisturbed_fast_rotation_B" in available_datasets():
        # BROAD's IMU comes calibrated and its motion cannot separate the accelerometer: the paper's filter
        cases.append(("BROAD 07 fast rotation 285.7 Hz", "dataset:broad/07_undisturbed_fast_rotation_B", "calibrated"))
    print(f"{'recording':<34} {'samples':>8} {'read s':>8} {'boundary s':>11} {'re-check s':>11} {'calibrate s':>12} "
          f"{'overhead':>9} {'(wall)':>7}")
    for name, path, accelerometer in cases:
        rows = []
        for _ in range(args.repeats):
            t_read, (raw, info) = _time(lambda: read_recording(path))
            t_bound, loaded = _time(lambda: prepare_recording(raw, KF, info=info))
            t_check, _ = _time(lambda: check_recording(loaded.recording, requirements=KF))
            t_cal, _ = _time(lambda: calibrate(loaded.recording, accelerometer=accelerometer))
            cpu = [x[0] for x in (t_read, t_bound, t_check, t_cal)]
            wall = [x[1] for x in (t_read, t_bound, t_check, t_cal)]
            rows.append(cpu + [(cpu[1] + cpu[2]) / (cpu[0] + cpu[3] - cpu[2]),
                               (wall[1] + wall[2]) / (wall[0] + wall[3] - wall[2])])
        med = [statistics.median(c) for c in zip(*rows)]
        print(f"{name:<34} {loaded.recording.n:8d} {med[0]:8.3f} {med[1]:11.3f} {med[2]:11.3f} {med[3]:12.3f} "
              f"{100 * med[4]:8.1f}% {100 * med[5]:6.1f}%")


if __name__ == "__main__":
    main()
