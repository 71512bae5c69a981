"""``calib lab closeloop-bench``: the library function the command prints, on a session the test passes."""

from __future__ import annotations

from calib.scoring.speed import closeloop_bench


def test_closeloop_bench_times_both_on_a_session_the_gyro_filter_accepts(typical_session):
    """The zhou2020 schedule cannot determine the accelerometer: the bench's filter takes it as calibrated (with it
    estimated the filter refuses the session, which made the command exit 2)."""
    (row,) = closeloop_bench([("zhou2020, typical hand (truth)", typical_session)])
    assert row.samples == typical_session.t_s.size
    assert row.closeloop_s > 0 and row.filter_s > 0 and row.ratio > 0
