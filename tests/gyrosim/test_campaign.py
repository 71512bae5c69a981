"""Campaigns on Dask, the estimator interface, and their bad input.

The Dask test starts a real LocalCluster (2 worker processes on 127.0.0.1) and checks that the
results of 2 presets × 3 seeds equal, number for number, the same campaign run in-process: the
tasks are pure functions of their spec, so the number of workers cannot change a result.
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np
import pytest

from gyrosim.campaign import CampaignSpec, load_campaign, make_tasks, run_campaign, summarise
from gyrosim.errors import GyrosimError
from gyrosim.estimator import Estimate, load_estimator

SMALL = CampaignSpec(
    hands=("ideal", "typical"), seeds=3, estimators=("kf", "kf_adaptive"), calibrated_accelerometer=True
)


def _rows(path: Path) -> list[dict]:
    with path.open(newline="") as fh:
        return [{k: v for k, v in r.items() if k != "task_seconds"} for r in csv.DictReader(fh)]


@pytest.fixture(scope="module")
def in_process(tmp_path_factory):
    out = tmp_path_factory.mktemp("inproc")
    return run_campaign(SMALL, out, scheduler=None)


def test_local_cluster_gives_the_same_results_as_in_process(in_process, tmp_path):
    pytest.importorskip("dask.distributed")
    path = run_campaign(SMALL, tmp_path / "dask", scheduler="local", workers=2)
    a, b = _rows(in_process), _rows(path)
    assert len(a) == len(b) == 2 * 3 * 2
    assert a == b
    assert all(r["status"] == "ok" for r in a)


def test_results_have_provenance_summary_and_a_physical_trend(in_process):
    out = in_process.parent
    prov = (out / "provenance.json").read_text()
    assert '"gyrosim"' in prov and '"mujoco"' in prov and '"spec"' in prov
    summary = summarise(in_process, out)
    by = {(r["hand"], r["estimator"]): r for r in summary}
    # the ideal hand adds no external acceleration; the typical one does (0.09 m/s² RMS)
    assert by[("ideal", "kf")]["ext_acc_rms_m_s2"] < 1e-4 < 0.05 < by[("typical", "kf")]["ext_acc_rms_m_s2"]
    assert by[("typical", "kf")]["rms_G_pct"] > by[("ideal", "kf")]["rms_G_pct"]
    for r in summary:
        assert r["rms_S_pct_lo"] <= r["rms_S_pct"] <= r["rms_S_pct_hi"]
    assert (out / "summary.csv").is_file() and (out / "error_vs_severity.png").stat().st_size > 1000
    # summary.rrd (what a person sees on opening it): the summary as plots against the external acceleration, every cell
    # on x, S and G errors on one log10 scale
    from gyrosim.viewer import read_blueprint, read_texts

    views = {v.origin: v for v in read_blueprint(out / "summary.rrd", sequence_timelines=["ext_acc_rms_mm_s2"])}
    s_view, g_view = views["campaign/log10_rms_S_pct"], views["campaign/log10_rms_G_pct"]
    assert s_view.y_range == g_view.y_range and "campaign/failed_pct" in views
    lo, hi = s_view.time_ranges["ext_acc_rms_mm_s2"]
    assert all(lo <= round(r["ext_acc_rms_m_s2"] * 1000) <= hi for r in summary)
    assert "kf: S error" in read_texts(out / "summary.rrd")["story"]


def test_rerun_skips_finished_tasks(in_process):
    calls = []
    run_campaign(SMALL, in_process.parent, scheduler=None, progress=lambda d, n: calls.append(n))
    assert calls == []  # nothing left to run
    assert len(_rows(in_process)) == 12


def test_adding_an_estimator_runs_only_it_and_keeps_the_rows(tmp_path):
    one = CampaignSpec(hands=("ideal",), seeds=1, estimators=("kf",), calibrated_accelerometer=True)
    path = run_campaign(one, tmp_path, scheduler=None)
    first = _rows(path)
    ran = []
    path = run_campaign(CampaignSpec(hands=("ideal",), seeds=1, estimators=("kf", "kf_session_r"),
                                     calibrated_accelerometer=True), tmp_path, scheduler=None,
                        progress=lambda d, n: ran.append(n))
    rows = _rows(path)
    assert ran == [1] and [r["estimator"] for r in rows] == ["kf", "kf_session_r"]
    assert rows[0] == first[0]


def test_a_failing_estimator_is_recorded_and_the_campaign_goes_on(tmp_path, monkeypatch):
    mod = tmp_path / "my_estimators.py"
    mod.write_text(
        "import numpy as np\n"
        "from gyrosim.estimator import Estimate\n"
        "def broken(rec):\n    raise RuntimeError('no convergence here')\n"
        "def zeros(rec):\n    return Estimate(np.zeros(3), np.zeros(3), np.zeros(3))\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = CampaignSpec(hands=("ideal",), seeds=1, estimators=("my_estimators:broken", "my_estimators:zeros"),
                        calibrated_accelerometer=True)
    rows = _rows(run_campaign(spec, tmp_path / "out", scheduler=None))
    assert [r["status"] for r in rows] == ["failed", "ok"]
    assert "no convergence here" in rows[0]["error"]
    assert float(rows[1]["err_S_x_pct"]) != 0.0  # zeros vs the drawn device: the device's own scale error


def test_bad_input_fails_before_any_work(tmp_path):
    with pytest.raises(GyrosimError, match="cannot import module"):
        load_estimator("no_such_module_xyz:est")
    with pytest.raises(GyrosimError, match="unknown estimator"):
        run_campaign(CampaignSpec(estimators=("kalman",)), tmp_path / "a", scheduler=None)
    assert not (tmp_path / "a").exists()
    toml = tmp_path / "c.toml"
    toml.write_text('hands = ["ideal"]\nseeds = 2\nsensors = "mpu9250"\n')
    with pytest.raises(GyrosimError, match="unknown key"):
        load_campaign(toml)
    toml.write_text('hands = ["ideal"]\nseeds = 2\nseverity = [0.0, 0.5]\n')
    spec = load_campaign(toml)
    assert [t.severity for t in make_tasks(spec)] == [0.0, 0.0, 0.5, 0.5]
    pytest.importorskip("dask.distributed")
    t0 = time.perf_counter()
    with pytest.raises(GyrosimError, match="did not answer within 2 s"):
        run_campaign(CampaignSpec(hands=("ideal",), seeds=1, estimators=("kf",)), tmp_path / "b",
                     scheduler="tcp://127.0.0.1:9", connect_timeout_s=2.0)
    assert time.perf_counter() - t0 < 20


def test_estimate_interface_checks_shapes():
    with pytest.raises(GyrosimError, match="3 values"):
        Estimate(np.zeros(2), np.zeros(3), np.zeros(3))
    assert Estimate(np.zeros(3), np.ones(3), np.zeros(3)).vector().shape == (9,)


def test_campaign_row_round_trips_through_the_csv(tmp_path):
    """A typed row written to results.csv and read back is the same row, and rewriting the file
    changes no byte (a resumed campaign rewrites what it read)."""
    from gyrosim.campaign import PARAMS, RESULT_COLUMNS, CampaignRow, read_rows, write_rows

    ok = CampaignRow("typical|1|3", "typical", 1.0, 3, "mpu9250 (calibrated acc)", "zhou2020", 100.0, "kf", "ok",
                     ext_acc_rms_m_s2=0.0917, rate_disturbance_rms_deg_s=0.61, task_seconds=1.234,
                     err=tuple(0.1 * i - 0.3 for i in range(9)), sd=tuple(1e-3 * (i + 1) / 7 for i in range(9)),
                     calibration_status="inconsistent")
    failed = CampaignRow("shaky|2|4", "shaky", 2.0, 4, "mpu9250", "zhou2020", 100.0, "kf_hand", "failed",
                         error="simulation: ReachError: beyond the arm's reach")
    path = tmp_path / "results.csv"
    write_rows(path, [ok.to_csv(), failed.to_csv()], RESULT_COLUMNS)
    back = [CampaignRow.from_csv(r) for r in read_rows(path)]
    assert back == [ok, failed]
    assert read_rows(path)[1][f"sd_{PARAMS[0]}"] == ""   # a failed row has no scores
    first = path.read_bytes()
    write_rows(path, [r.to_csv() for r in back], RESULT_COLUMNS)
    assert path.read_bytes() == first


def test_workers_spawn_without_a_malloc_trim_threshold(monkeypatch):
    """Setting MALLOC_TRIM_THRESHOLD_ at all switches off glibc's dynamic mmap threshold (every
    temporary above 128 KiB becomes an mmap with fresh page faults: 30x the page faults, +50 % CPU
    per session measured); the campaign's Dask config leaves it out of the worker environment."""
    import dask
    from distributed.nanny import _get_env_variables

    from gyrosim.campaign import DASK_CONFIG

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    with dask.config.set(DASK_CONFIG):
        env = _get_env_variables("distributed.nanny.pre-spawn-environ")
    assert "MALLOC_TRIM_THRESHOLD_" not in env and env.get("OMP_NUM_THREADS") == "1"
