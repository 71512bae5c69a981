"""Plug your own estimator into a campaign and compare it with ours.

An estimator is any callable Recording -> Calibration (gyrosim.estimator, gyrosim.calibration).  This one is a user's
first idea: "the hand is slow, so ignore the external acceleration but average the accelerometer
over 0.5 s before it enters the filter" — implemented here by low-passing the accelerometer and
running our Zhou filter kernel on it.  Run:

    python examples/own_estimator.py            # in-process, 2 hands × 3 seeds
    gyrosim campaign --method kf,kf_adaptive,examples.own_estimator:lowpassed_acc_kf \
        --hand typical,shaky --seeds 20 --calibrated-accelerometer --out results/   # from the checkout root

The campaign imports the estimator by its path (package.module:attribute), so it must be
importable where the tasks run (for a remote Dask cluster: installed on the workers).  An installed
package can instead register it under a short name in the entry-point group ``gyrosim.estimators``
(see pyproject.toml, where calib registers ``kf`` and the others).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import signal

from gyrosim.calibration import Calibration
from gyrosim.recording import Recording


def lowpassed_acc_kf(rec: Recording) -> Calibration:
    """Zhou's filter on an accelerometer low-passed at 2 Hz (zero-phase), R from the session."""
    from calib.session.registry import kf_session_r

    b, a = signal.butter(2, 2.0 / (rec.rate_hz / 2))
    smooth = signal.filtfilt(b, a, np.asarray(rec.acc_m_s2), axis=0)
    return kf_session_r(rec.with_signals(acc_m_s2=smooth))


def main() -> int:
    """Run a small campaign in-process (two hands × 3 seeds) of ``kf``, ``kf_adaptive`` and
    :func:`lowpassed_acc_kf`, and print each one's RMS error of S and G (%)."""
    from gyrosim.campaign import CampaignSpec, run_campaign, summarise

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # make examples.own_estimator importable
    spec = CampaignSpec(hands=("ideal", "typical"), seeds=3, sensor="mpu9250", calibrated_accelerometer=True,
                        estimators=("kf", "kf_adaptive", "examples.own_estimator:lowpassed_acc_kf"))
    out = Path(tempfile.mkdtemp(prefix="own_estimator_"))
    path = run_campaign(spec, out, scheduler=None)
    for r in summarise(path, out):
        print(f"{r['hand']:<8} {r['estimator']:<42} S err {r['rms_S_pct']:.4f} %   G err {r['rms_G_pct']:.4f} %")
    print(f"results in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
