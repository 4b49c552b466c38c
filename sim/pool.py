"""Worker process pools that never outlive the process that started them.

A ``ProcessPoolExecutor``'s workers are separate processes: when their parent is killed with
SIGKILL (a user's ``kill -9``, an out-of-memory kill, the resume tests), nothing tells them, and
they sleep on, re-parented to PID 1, holding 100-200 MB each. Every pool of this package (FE
sweeps and confirmations, the references' FE beside the search, figures) is made by
``process_pool``, whose workers

- run single-threaded BLAS/OpenMP (one worker per core: threads would oversubscribe the cores),
- watch their parent: a daemon thread checks every ``PARENT_POLL_S`` seconds whether the
  parent's PID is still theirs, and ends the worker (``os._exit``) as soon as it is not.

A worker writes nothing itself (only the parent writes records), so ending it loses nothing.
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor

__all__ = ["PARENT_POLL_S", "process_pool", "worker_init"]

#: how often a worker looks for its parent (s): an orphan lives at most this long
PARENT_POLL_S = 0.5
#: the exit status of a worker that found itself orphaned
ORPHAN_EXIT_STATUS = 70


def _single_thread() -> None:
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"


def _exit_with_parent(parent: int) -> None:
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(ORPHAN_EXIT_STATUS)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def worker_init(parent: int) -> None:
    """The initializer of every worker of ``process_pool`` (module level: picklable)."""
    _single_thread()
    _exit_with_parent(parent)


def process_pool(workers: int) -> ProcessPoolExecutor:
    """A ``ProcessPoolExecutor`` of ``workers`` single-threaded processes that end with their
    parent (see the module docstring)."""
    return ProcessPoolExecutor(
        max_workers=workers, initializer=worker_init, initargs=(os.getpid(),)
    )
