"""Dask is the ``campaign`` extra: without it a campaign on a scheduler says how to install it, and one in this
process runs as before."""

from __future__ import annotations

import sys

import pytest

from gyrosim.campaign import run_tasks
from gyrosim.errors import GyrosimError


def test_a_campaign_on_a_scheduler_without_dask_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import dask.distributed now raises ImportError
    with pytest.raises(GyrosimError, match=r"gyrosim-calib\[campaign\].*--scheduler none"):
        run_tasks([1], lambda t: [t], [], lambda: None, scheduler="local", workers=1, connect_timeout_s=1.0,
                  progress=None, key_prefix="t")


def test_a_campaign_in_this_process_needs_no_dask(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    rows, flushes = [], []
    run_tasks([1, 2, 3], lambda t: [t * 10], rows, lambda: flushes.append(len(rows)), scheduler="none", workers=None,
              connect_timeout_s=1.0, progress=None, key_prefix="t")
    assert rows == [10, 20, 30] and flushes == [3]


def test_the_campaign_view_keeps_identical_estimators_visible_and_small_changes_small(tmp_path):
    from gyrosim.campaign import save_summary_rrd
    from gyrosim.viewer import read_blueprint, read_series_styles, read_texts

    rows = []
    for hand, acc, s_pct in (("ideal", 0.01, 0.100), ("typical", 0.2, 0.103), ("shaky", 0.6, 0.105)):
        for est in ("iterated", "kf"):  # the same numbers in every cell
            rows.append({"estimator": est, "hand": hand, "n": 10, "failed": 0, "ext_acc_rms_m_s2": acc,
                         "rms_S_pct": s_pct, "rms_G_pct": 0.05, "rms_bias_deg_s": 0.01})
    path = save_summary_rrd(rows, tmp_path / "summary.rrd")
    views = {v.origin: v for v in read_blueprint(path, sequence_timelines=["ext_acc_rms_mm_s2"])}
    for g in ("S_pct", "G_pct", "bias_deg_s"):
        v = views[f"campaign/log10_rms_{g}"]
        # a 5 % change is 0.02 decade: on at least half a decade of y it stays a small step, not a V
        assert v.y_range is not None and v.y_range[1] - v.y_range[0] >= 0.5 and "mm/s²" in v.name
    first, second = (read_series_styles(path)[f"campaign/log10_rms_S_pct/{e}"] for e in ("iterated", "kf"))
    assert first[1] != second[1] and first[2] > second[2]  # two colours, and the one drawn first is wider
    assert "iterated = kf" in read_texts(path)["story"]
