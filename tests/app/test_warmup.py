"""The demo's background compile of the filter (calib.app.warmup.FilterWarmup): it only ever adds — a failing,
missing or slow child leaves the compile to the command, and no child outlives the ``with`` block."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from calib.app.warmup import FilterWarmup

SLEEPER = (sys.executable, "-c", "import time; time.sleep(60)")


def _gone(pid: int) -> bool:
    """True when ``pid`` no longer exists (reaped)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_a_finished_child_is_ready_and_a_failing_one_reported_without_raising():
    with FilterWarmup((sys.executable, "-c", "pass")) as ok:
        deadline = time.monotonic() + 30
        while ok.running and time.monotonic() < deadline:   # finished before the first filter run: nothing to say
            time.sleep(0.05)
        said = []
        assert ok.wait(said.append) == "ready" and said == []
    with FilterWarmup((sys.executable, "-c", "raise SystemExit(3)")) as bad:
        assert bad.wait() == "failed (exit 3)"
    with FilterWarmup(("/nonexistent/python",)) as missing:    # cannot start: the run compiles in-process
        assert missing.wait().startswith("failed") and missing.pid is None


def test_a_child_still_compiling_is_waited_for_with_one_line_and_ended_after_the_timeout():
    said = []
    with FilterWarmup(SLEEPER, timeout_s=0.5) as w:
        pid = w.pid
        assert w.running
        t0 = time.monotonic()
        assert w.wait(said.append) == "timed out"
        assert time.monotonic() - t0 < 10                  # 0.5 s, then terminate and reap
    assert said == ["compiling the filter (once per machine; later runs reuse it) …"]
    assert _gone(pid)


def test_leaving_the_block_ends_a_child_still_running():
    with FilterWarmup(SLEEPER) as w:
        pid = w.pid
    assert w.outcome == "ended" and _gone(pid)
    with pytest.raises(RuntimeError):                      # also when the demo fails
        with FilterWarmup(SLEEPER) as w:
            pid = w.pid
            raise RuntimeError("the simulation failed")
    assert _gone(pid)


@pytest.mark.slow
def test_the_child_fills_the_cache_the_command_then_loads(tmp_path, monkeypatch):
    # ~20-45 s: a real compile into an empty numba cache, then a fresh process loads it (a compile would take as long)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))       # the child inherits this process's environment
    with FilterWarmup() as w:
        assert w.wait() == "ready"
    assert list(tmp_path.rglob("*.nbi")), "numba's cache index was not written"
    code = ("import time; t = time.perf_counter(); from calib.session.kernel import warm_up; warm_up(); "
            "print(time.perf_counter() - t)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert float(run.stdout) < 10, run.stdout             # loaded from the cache (a compile: ≥ 15 s on 2 cores)


def test_a_slow_block_is_announced_once_and_a_quick_one_not_at_all():
    """``calib run``'s in-process warm-up: loading the loop from the cache takes under a second and says nothing;
    compiling it (a cold cache, ~20 s) is announced once, while it runs.  Timings with a 10× margin either way."""
    from calib.app.warmup import COMPILING, announce_if_slow

    said = []
    with announce_if_slow(said.append, after_s=0.5):
        time.sleep(0.05)
    time.sleep(0.8)                                        # past the delay: a cancelled timer stays silent
    assert said == []
    with announce_if_slow(said.append, after_s=0.05):
        time.sleep(0.5)
        assert said == [COMPILING]                         # said while the block still runs
    assert said == [COMPILING]
