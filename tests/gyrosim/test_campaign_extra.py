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
