"""How many threads torch's operators use while a surrogate trains (:func:`torch_threads`), and
the block that sets them and gives the caller's back afterwards (:func:`threads_set`).

Training (``fingertip train``) and the search's retraining (``explore._retrain``) both run
``surrogate._train.fit`` inside :func:`threads_set`; the count used is recorded in the
checkpoint's header (``training.torch_threads``) and, for ``fingertip train``, in the run
folder's ``config.json`` and ``meta.json``.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["MAX_TRAINING_THREADS", "threads_set", "torch_threads"]

#: The most intra-op threads a training or a retraining uses: 1. Two reasons, either enough:
#:
#: - The same bits whatever the machine. torch's CPU reductions split a tensor larger than their
#:   grain (32 768 elements) into one chunk per thread and add the chunks' sums: the result
#:   depends on the thread count (torch 2.13, this venv: the sum of 4e6 normal floats differs
#:   between 1 and 2 threads, that of a 10 x 2000 x 40 tensor between 1 and 8). The project
#:   promises the same answer from the same inputs and seed whatever the number of workers or
#:   threads, and a retrained surrogate decides the next round's search. The shipped ensemble's
#:   tensors happen to stay under the grain (a 3-epoch fine-tune of the shipped checkpoint on
#:   its sweep gave the same weights, bit for bit, at 1, 2, 4 and 8 threads), but a larger
#:   ensemble, validation set or minibatch would not: one thread makes it hold by construction.
#: - No speed to gain, much to lose. The nets are small (minibatches of 32, 96 hidden units): a
#:   thread's share of a product is too small to pay for the pool's synchronisation, and beside
#:   the FE workers (or any other job) torch's default pool, one thread per core, waits on
#:   descheduled threads at every operation: retraining took 577-662 s with the default threads
#:   against 35 s with OMP_NUM_THREADS=1 (issue 31, item 4). A 3-epoch fine-tune of the shipped
#:   checkpoint (quick checks on 2 cores, other engineers' jobs running): 3.3 s on 1 thread,
#:   5-6 s on 4 or 8, and once 68 s on 2 while those jobs took a core.
#:
#: Raising it (a bigger model that gains from threads, where bits across machines do not
#: matter) keeps :func:`torch_threads`'s other rule: never more threads than the cores left by
#: the FE workers running at the same time.
#:
#: ``torch.set_num_interop_threads`` is left alone: the inter-op pool runs only work started by
#: ``torch.jit.fork`` / TorchScript, which training never uses (after a fine-tune it is still
#: unstarted: ``set_num_interop_threads`` succeeds), and it may be called only once per
#: process, before that pool starts (a ``RuntimeError`` afterwards), so a library must not.
MAX_TRAINING_THREADS = 1


def torch_threads(fe_workers: int = 0, *, cores: int | None = None, most: int | None = None) -> int:
    """torch's intra-op threads for a training: the cores this process may use (``cores``;
    default: its CPU affinity, ``os.sched_getaffinity(0)``, as ``sim.sweep.run.default_workers``)
    less the ``fe_workers`` FE processes that run at the same time (one core each), at least 1
    and at most ``most`` (default :data:`MAX_TRAINING_THREADS`)."""
    if cores is None:
        from sim.sweep import default_workers

        cores = default_workers()
    most = MAX_TRAINING_THREADS if most is None else most
    return max(1, min(most, cores - max(0, fe_workers)))


@contextmanager
def threads_set(threads: int) -> Iterator[int]:
    """The block runs with ``threads`` intra-op threads (``torch.set_num_threads``); the count
    before it is set again afterwards. Yields ``threads``."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield threads
    finally:
        torch.set_num_threads(before)
