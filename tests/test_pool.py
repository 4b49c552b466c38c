"""Pool workers end with their parent, even when the parent is killed with SIGKILL."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim.pool import PARENT_POLL_S, process_pool

PARENT = """
import os, sys, time
from sim.pool import process_pool
pool = process_pool(2)
pids = sorted({f.result() for f in [pool.submit(os.getpid) for _ in range(8)]})
print(" ".join(map(str, pids)), flush=True)
time.sleep(600)
"""


def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, exited but not yet reaped, counts as ended)."""
    status = Path(f"/proc/{pid}/status")
    try:
        state = next(line for line in status.read_text().splitlines() if line.startswith("State"))
    except (FileNotFoundError, ProcessLookupError):
        return False
    return "Z" not in state.split()[1]


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_workers_end_when_their_parent_is_killed():
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdout=subprocess.PIPE, text=True)
    workers: list[int] = []
    try:
        workers = [int(p) for p in parent.stdout.readline().split()]
        assert workers and all(_alive(p) for p in workers)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 20 * PARENT_POLL_S + 5.0
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_alive(p) for p in workers), "a worker outlived its killed parent"
    finally:
        if parent.poll() is None:
            parent.kill()
        for pid in workers:  # a failed run leaves no orphan behind
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_workers_run_single_threaded_and_return_results(monkeypatch):
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    with process_pool(2) as pool:
        env = pool.submit(os.getenv, "OMP_NUM_THREADS").result()
        assert env == "1"
        assert sorted(pool.map(abs, [-3, -1, 2])) == [1, 2, 3]


def test_a_background_pool_runs_at_the_lowest_priority():
    """``nice``: the FE beside the rounds takes idle cores only (``explore._rounds``)."""
    here = os.nice(0)
    with process_pool(1, nice=19) as pool:
        assert pool.submit(os.nice, 0).result() == min(here + 19, 19)
    with process_pool(1) as pool:
        assert pool.submit(os.nice, 0).result() == here


def test_stop_workers_ends_a_busy_worker_at_once():
    """A starved background worker is stopped, not waited for (``explore._rounds``)."""
    import time

    from sim.pool import stop_workers

    pool = process_pool(1, nice=19)
    future = pool.submit(time.sleep, 60)
    while not future.running():
        time.sleep(0.01)
    workers = [p.pid for p in pool._processes.values()]
    t0 = time.perf_counter()
    stop_workers(pool)
    assert time.perf_counter() - t0 < 5
    assert workers and not any(_alive(w) for w in workers)
    pool.shutdown(wait=True)


INTERRUPTED = """
import os, signal, sys, time
# Ctrl-C as in a shell's foreground process, whatever the test process left to its children
# (an ignored or blocked SIGINT is inherited across exec, and the full suite leaves one)
signal.signal(signal.SIGINT, signal.default_int_handler)
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
from explore.cli import _terminate_as_interrupt
from sim.pool import process_pool
restore = _terminate_as_interrupt()  # what `fingertip` does
try:
    with process_pool(2, spawn=True) as pool:  # spawned: its queues' semaphores are tracked
        # both workers up (each has answered), whatever the load: a signal that reaches a
        # worker still importing is another case than the one tested here
        seen, deadline = set(), time.monotonic() + 120
        while len(seen) < 2 and time.monotonic() < deadline:
            seen.update(f.result() for f in [pool.submit(os.getpid) for _ in range(4)])
        futures = [pool.submit(time.sleep, 60) for _ in range(4)]
        time.sleep(1)  # the workers have taken their sleeps
        print(" ".join(map(str, pool._processes)), flush=True)
        futures[0].result()
except KeyboardInterrupt as exc:
    print(type(exc).__name__, file=sys.stderr)
    sys.exit(1)
finally:
    restore()
"""


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
@pytest.mark.parametrize("how", ["SIGTERM", "Ctrl-C"])
def test_an_interrupted_pool_stops_its_workers_and_leaks_nothing(how):
    """Issue 31, item 6d: SIGTERM (a `kill`) or Ctrl-C (SIGINT to the whole process group)
    during a pool's work: the parent stops its workers at once instead of waiting for the
    queued work, ends normally, and the resource tracker finds no "leaked semaphore objects"
    (SIGTERM killed the parent outright, Ctrl-C left it waiting for the queue)."""
    parent = subprocess.Popen(
        [sys.executable, "-c", INTERRUPTED], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, start_new_session=True,
    )  # fmt: skip
    workers: list[int] = []
    try:
        workers = [int(p) for p in parent.stdout.readline().split()]
        assert len(workers) == 2 and all(_alive(p) for p in workers)
        if how == "SIGTERM":
            os.kill(parent.pid, signal.SIGTERM)
        else:
            os.killpg(parent.pid, signal.SIGINT)
        _, err = parent.communicate(timeout=30)  # its work would take 60 s and more
        assert parent.returncode == 1, err
        assert err.splitlines()[0] == ("_Terminated" if how == "SIGTERM" else "KeyboardInterrupt")
        assert "leaked" not in err and "Traceback" not in err, err
        assert not any(_alive(p) for p in workers)
    finally:
        if parent.poll() is None:
            parent.kill()
        for pid in workers:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
