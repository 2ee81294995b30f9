"""Bounded, order-preserving parallel map over worker processes or threads (for frame streams)."""

from __future__ import annotations

import multiprocessing
import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor
from typing import TypeVar

__all__ = ["ordered_map", "cap_workers", "cpu_count", "exit_with_parent"]

_PARENT_POLL_S = 0.5  # how often a worker checks that the process that started it still runs

T = TypeVar("T")
R = TypeVar("R")


def cpu_count() -> int:
    """Cores this process may run on (the affinity mask where the platform has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def cap_workers(requested: int, n_items: int) -> int:
    """Workers to start: ``requested`` (0 = one per core), never more than the cores or the work items.

    >>> cap_workers(10000, 3) <= 3
    True
    """
    cores = cpu_count()
    want = cores if requested <= 0 else requested
    return max(1, min(want, cores, max(1, n_items)))


def exit_with_parent(parent_pid: int) -> None:
    """Worker initializer: end this process as soon as its parent ``parent_pid`` is gone.

    A pool's workers wait for work from their parent; killed (out of memory, SIGKILL), it never
    sends any, and each worker keeps the others' end of the queue open, so they would wait forever,
    re-parented to init. A daemon thread compares ``os.getppid()`` with ``parent_pid`` every
    half-second (the parent *process*, whichever of its threads started the pool: unlike Linux's
    ``PR_SET_PDEATHSIG``, which fires when that thread ends) and ends the worker at once when it differs.
    """
    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(_PARENT_POLL_S)
        os._exit(1)  # nothing left to report to: no cleanup that could wait on the dead parent

    if os.getppid() != parent_pid:  # died before this worker got here
        os._exit(1)
    threading.Thread(target=watch, name="rotavat-exit-with-parent", daemon=True).start()


def _executor(workers: int, processes: bool) -> Executor:
    """A process pool (fork on Linux: cheap start, inherited imports; workers end with this process)
    or a thread pool."""
    if not processes:
        return ThreadPoolExecutor(max_workers=workers)
    method = "fork" if sys.platform.startswith("linux") else "spawn"
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(method),
                               initializer=exit_with_parent, initargs=(os.getpid(),))


def ordered_map(fn: Callable[[T], R], items: Iterable[T], workers: int = 2, window: int | None = None,
                processes: bool = False, meanwhile: Callable[[], None] | None = None) -> Iterator[R]:
    """Yield ``fn(item)`` in input order, at most ``window`` items in flight (default 2 x workers).

    ``workers <= 1`` runs inline. With ``processes`` the work runs in worker processes (``fn`` and
    items must pickle): true parallelism for numpy code that holds the GIL between small calls.
    An exception in ``fn`` is raised when its result is reached; pending work is cancelled.
    ``meanwhile``: run in this thread once the first window of items is in flight (inline: first), e.g.
    imports the caller needs next; with fork the workers are all started by then, so it may import freely.

    >>> list(ordered_map(lambda x: x * x, range(5), workers=2))
    [0, 1, 4, 9, 16]
    """
    if workers <= 1:
        if meanwhile is not None:
            meanwhile()
        yield from map(fn, items)
        return
    window = window or 2 * workers
    pending: deque[Future] = deque()
    with _executor(workers, processes) as pool:
        try:
            for item in items:
                pending.append(pool.submit(fn, item))
                if len(pending) >= window:
                    if meanwhile is not None:
                        meanwhile, run = None, meanwhile
                        run()
                    yield pending.popleft().result()
            if meanwhile is not None:
                meanwhile()
            while pending:
                yield pending.popleft().result()
        finally:
            for future in pending:
                future.cancel()
