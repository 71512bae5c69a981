"""The magnetometer cases of the closeloop suite over 10 seeds (docs/magnetometer.md
has the 20-seed table of ``calib closeloop-suite --cases mag --seeds 20``).

Criteria (the issue): the right cause named in ≥ 9/10 seeds, the room anomaly reported as
unexplained structure in ≥ 9/10, nothing added on a clean session in ≥ 9/10.  σ honesty: the
normalised errors z = (θ̂ − θ)/σ̂ of every named parameter over the seeds have mean z² ≤ 2 (for
honest σ E z² = 1; with 30–50 values its standard error is 0.2–0.26, so 2 is > 3.8 standard errors
above 1 — a σ too small by a factor 1.4 fails).
"""

from __future__ import annotations

import numpy as np
import pytest

from calib.closeloop.suite import MAG_SUITE, run_suite

pytestmark = pytest.mark.slow


def test_magnetometer_suite_names_the_cause_in_9_of_10_seeds():
    rows = {r.case: r for r in run_suite(list(MAG_SUITE), range(100, 110))}
    for case in ("hard_iron", "soft_iron", "frame_rotation"):
        r = rows[case]
        assert r.named_first >= 9 and r.named_all >= 9, (case, r.found)
        assert r.forbidden_added <= 1, (case, r.found)
    assert rows["room_anomaly"].named_all >= 9, rows["room_anomaly"].found
    assert rows["mag_negative"].seeds - rows["mag_negative"].added_anything >= 9, rows["mag_negative"].found


@pytest.mark.parametrize("case", ["hard_iron", "soft_iron", "frame_rotation"])
def test_magnetometer_loop_sigma_is_honest_over_seeds(case):
    from calib.closeloop.suite import run_case

    z = []
    for seed in range(200, 210):
        res = run_case(case, None, seed)
        if res.named_all:
            z.append((res.estimate - res.truth) / res.sigma)
    z = np.concatenate(z)
    assert z.size >= 27
    assert np.mean(z**2) <= 2.0, np.mean(z**2)
