"""Worker process pools that never outlive the process that started them.

A ``ProcessPoolExecutor``'s workers are separate processes: when their parent is killed with
SIGKILL (a user's ``kill -9``, an out-of-memory kill, the resume tests), nothing tells them, and
they sleep on, re-parented to PID 1, holding 100-200 MB each. Every pool of this package (FE
sweeps and confirmations, the references' FE beside the search, figures) is made by
``process_pool``, whose workers

- run single-threaded BLAS/OpenMP (one worker per core: threads would oversubscribe the cores),
- watch their parent: a daemon thread checks every ``PARENT_POLL_S`` seconds whether the
  parent's PID is still theirs, and ends the worker (``os._exit``) as soon as it is not.

A worker's records are written atomically (the references' and the screen's FE beside the
search write their own), so ending it loses at most the designs it was running.

Interrupted (Ctrl-C, or SIGTERM, which ``fingertip`` turns into the same ``KeyboardInterrupt``),
a pool stops its workers at once instead of waiting for their work (:meth:`Pool.__exit__`), and
the process then ends normally, so the locks and semaphores of its queues are released (a
process that died of SIGTERM left them to the resource tracker: "There appear to be 5 leaked
semaphore objects to clean up at shutdown"). The workers ignore Ctrl-C themselves: it reaches
the whole process group, and their parent decides (a worker's own ``KeyboardInterrupt`` printed
a traceback and failed its design). Only SIGKILL leaves no time for any of this.

A pool made with ``nice`` > 0 runs at a lower priority: it takes the cores only when the rest of
the job leaves them idle (the FE beside the search, ``explore._rounds.fe_alongside``).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from types import TracebackType

__all__ = ["PARENT_POLL_S", "Pool", "process_pool", "stop_workers", "worker_init"]

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


def worker_init(parent: int, nice: int = 0) -> None:
    """The initializer of every worker of ``process_pool`` (module level: picklable)."""
    _single_thread()
    _exit_with_parent(parent)
    # Ctrl-C is the parent's to handle (it stops the pool); SIGTERM ends a worker as usual,
    # whatever handler a forked worker inherited from its parent
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if nice > 0 and hasattr(os, "nice"):
        os.nice(nice)


class Pool(ProcessPoolExecutor):
    """A ``ProcessPoolExecutor`` that, left by an interruption, stops its workers at once."""

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> bool:
        """Leaving a ``with`` block: normally, wait for the work (as ``ProcessPoolExecutor``);
        interrupted (``KeyboardInterrupt``, ``SystemExit``), :func:`stop_workers` at once; on
        an error, cancel the work not started and wait for the running designs."""
        if exc_type is None:
            self.shutdown(wait=True)
        elif issubclass(exc_type, KeyboardInterrupt | SystemExit):
            stop_workers(self)
        else:
            self.shutdown(wait=True, cancel_futures=True)
        return False


def process_pool(workers: int, nice: int = 0, *, spawn: bool = False) -> Pool:
    """A ``Pool`` (a ``ProcessPoolExecutor`` that stops its workers when interrupted) of
    ``workers`` single-threaded processes that end with their parent, at ``nice`` (0: the
    parent's priority; up to 19, the lowest) (see the module docstring). ``spawn``: fresh
    interpreters instead of forks of this process, for work that uses torch when this process
    has used it (a fork inherits its thread pools' locks in whatever state they were, and can
    wait on them for ever)."""
    import multiprocessing

    return Pool(
        max_workers=workers,
        initializer=worker_init,
        initargs=(os.getpid(), nice),
        mp_context=multiprocessing.get_context("spawn") if spawn else None,
    )


def stop_workers(pool: ProcessPoolExecutor) -> None:
    """End ``pool``'s workers now (SIGKILL) and cancel its queued work: a worker loses the
    design it was running (records are written atomically), nothing else. For a pool at a low
    priority whose work is no longer worth waiting for: on a loaded machine a worker at nice 19
    gets almost no CPU, and waiting for it would stall the job."""
    # the worker processes (Python 3.14 has ``pool.kill_workers()``; 3.11 keeps them here)
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        proc.kill()
    for proc in processes:
        proc.join()
