"""Compile the session filter in a background process while something else runs (the demo's simulation).

The filter's compiled loop (:mod:`calib.session.kernel`) takes numba ~20 s to compile the first time on a machine;
numba then keeps it in its cache and later runs load it in well under a second.  :class:`FilterWarmup` starts a
child Python that compiles it into that cache (:func:`calib.session.kernel.warm_up`) on the second core while this
process does other work; :meth:`FilterWarmup.wait` is called before the first filter run and waits for the child,
so the run then loads the loop from the cache instead of compiling it again.  The child only ever adds: when it
cannot start, fails or is too slow, this process compiles in-process as it would have without it; leaving the
``with`` block ends a child still running (no process outlives the command); numba writes each cache file
atomically, and this process waits for the child rather than compiling alongside it.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator, Sequence

__all__ = ["FilterWarmup", "WARMUP_COMMAND", "COMPILING", "announce_if_slow"]

# what the person at the terminal reads while the filter compiles (the first run on a machine)
COMPILING = "compiling the filter (once per machine; later runs reuse it) …"

# the child: import the kernel from the same calib as this process and compile (or load) its loop
WARMUP_COMMAND = (sys.executable, "-c", "from calib.session.kernel import warm_up; warm_up()")


class FilterWarmup:
    """A child process compiling the filter into numba's cache, as a context manager (``with FilterWarmup() as w:
    …; w.wait(log); <first filter run>``).  ``command`` replaces the child's command line (tests);
    ``timeout_s`` bounds :meth:`wait`, after which the child is ended and this process compiles itself."""

    def __init__(self, command: Sequence[str] = WARMUP_COMMAND, timeout_s: float = 300.0):
        self.command = tuple(command)
        self.timeout_s = float(timeout_s)
        self._proc: subprocess.Popen | None = None
        self.outcome = "not started"   # then: "running", "ready" (exit 0), "failed (exit N)", "timed out", "ended"

    def __enter__(self) -> "FilterWarmup":
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[2])    # the folder holding this calib package: the child imports it
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        try:
            self._proc = subprocess.Popen(self.command, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL)
            self.outcome = "running"
        except OSError as exc:                              # no child: the first run compiles in-process
            self.outcome = f"failed ({exc.strerror or exc})"
        return self

    @property
    def pid(self) -> int | None:
        """The child's process id while it is held (None before it starts, after it is reaped or ended)."""
        return None if self._proc is None else self._proc.pid

    @property
    def running(self) -> bool:
        """True while the child is still compiling."""
        return self._proc is not None and self._proc.poll() is None

    def wait(self, log: Callable[[str], None] = lambda msg: None) -> str:
        """Before the first filter run: when the child is still at work (the cache was cold), say so through ``log``
        and wait for it; returns :attr:`outcome`."""
        if self._proc is None:
            return self.outcome
        if self._proc.poll() is None:
            log(COMPILING)
            try:
                self._proc.wait(self.timeout_s)
            except subprocess.TimeoutExpired:
                self._end()
                self.outcome = "timed out"
                return self.outcome
        code = self._proc.returncode
        self.outcome = "ready" if code == 0 else f"failed (exit {code})"
        self._proc = None
        return self.outcome

    def _end(self) -> None:
        """End a child still running and reap it."""
        if self._proc is None:
            return
        if self._proc.poll() is None:
            self._proc.terminate()
            try:
                self._proc.wait(5.0)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
            self.outcome = "ended"
        self._proc = None

    def __exit__(self, *exc) -> None:
        self._end()


@contextmanager
def announce_if_slow(log: Callable[[str], None], message: str = COMPILING, after_s: float = 2.0) -> Iterator[None]:
    """Say ``message`` through ``log`` (from a timer thread) when the block runs longer than ``after_s`` — around the
    filter's warm-up (:func:`calib.session.kernel.warm_up`), which loads the compiled loop from numba's cache in
    under a second and compiles it, ~20 s, only when the cache is cold: ``calib run``'s first run on a machine then
    says why it is silent."""
    timer = threading.Timer(after_s, log, args=(message,))
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
