"""Executors: one small interface (submit, wait, close) over this process, a process pool and a Dask client."""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing
import os
from collections.abc import Callable
from typing import Any

from ..errors import InputError
from ..parallel import cap_workers, exit_with_parent
from .plan import BatchOptions
from .tasks import one_line

__all__ = ["InlineExecutor", "LOCAL_CLUSTER_CONFIG", "POOL_WORKER_ENVIRON", "local_cluster", "make_executor"]


class InlineExecutor:
    """Runs each task at submission, in this process (``jobs=1``)."""

    name, workers, limit = "local", 1, 1

    def submit(self, fn: Callable, *args: Any) -> cf.Future:
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args))
        except Exception as exc:  # delivered through the future, like the other executors
            future.set_exception(exc)
        return future

    def wait(self, futures: list) -> set:
        return set(futures)

    def close(self, cancel: bool = False) -> None:
        pass


# One BLAS/OpenMP thread per pool worker, as Dask's nanny does for its workers: with one worker per
# core, multi-threaded BLAS only oversubscribes the cores. Measured on 6 sequences x 200 frames,
# --jobs 2: 34.3-35.5 s with these against 38.6-40.0 s without (calibrate's least_squares suffered
# most). A value the user exported wins; the driver's own environment is restored on close.
POOL_WORKER_ENVIRON = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class _PoolExecutor:
    """A process pool on this machine (spawned workers: no state forked from the driver; they end
    when the driver does, even killed: :func:`rotavat_cli.parallel.exit_with_parent`)."""

    name = "local"

    def __init__(self, jobs: int) -> None:
        self.workers, self.limit = jobs, jobs + 1  # one queued task so no worker waits for the driver
        # Workers are spawned lazily by submit, and inherit os.environ then: set it for the pool's life.
        self._added_env = {k: v for k, v in POOL_WORKER_ENVIRON.items() if k not in os.environ}
        os.environ.update(self._added_env)
        self._pool = self._new()

    def _new(self) -> cf.ProcessPoolExecutor:
        return cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
                                      initializer=exit_with_parent, initargs=(os.getpid(),))

    def submit(self, fn: Callable, *args: Any) -> cf.Future:
        try:
            return self._pool.submit(fn, *args)
        except cf.process.BrokenProcessPool:  # a worker died (killed, out of memory): its tasks failed; start afresh
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = self._new()
            return self._pool.submit(fn, *args)

    def wait(self, futures: list) -> set:
        return cf.wait(futures, return_when=cf.FIRST_COMPLETED).done

    def close(self, cancel: bool = False) -> None:
        self._pool.shutdown(wait=not cancel, cancel_futures=cancel)
        for key in self._added_env:
            os.environ.pop(key, None)


class _DaskExecutor:
    """Tasks submitted to a Dask distributed cluster: an existing one (``scheduler``) or a LocalCluster here."""

    name = "dask"

    def __init__(self, scheduler: str | None, jobs: int) -> None:
        try:
            import distributed  # lazy: optional extra rotavat[dask]
        except ImportError:
            raise InputError("--executor dask needs Dask: pip install 'rotavat[dask]' (or dask[distributed])") from None
        self._distributed, self._cluster = distributed, None
        try:
            if scheduler:
                self._client = distributed.Client(scheduler, timeout=20, set_as_default=False)
            else:
                self._cluster = local_cluster(jobs)
                self._client = distributed.Client(self._cluster, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({one_line(str(exc))})") from None
        if not self._client.nthreads():
            try:
                self._client.wait_for_workers(1, timeout=60)
            except (TimeoutError, OSError):
                self.close()
                raise InputError(f"the Dask cluster at {scheduler} has no workers") from None
        self.workers = sum(self._client.nthreads().values())
        self.limit = 2 * self.workers
        self.address = self._client.scheduler.address

    def submit(self, fn: Callable, *args: Any) -> Any:
        return self._client.submit(fn, *args, pure=False)

    def wait(self, futures: list) -> set:
        with self._client.as_current():  # distributed.wait uses the current client; ours is not the default
            return set(self._distributed.wait(futures, return_when="FIRST_COMPLETED").done)

    def close(self, cancel: bool = False) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()


# The Dask configuration of the LocalCluster rotavat starts itself (its scheduler, nannies and
# workers; the nannies hand it to the workers they spawn).
# - Worker environment (distributed.nanny.pre-spawn-environ): one BLAS/OpenMP thread per worker as
#   Dask sets it, but without MALLOC_TRIM_THRESHOLD_. Setting that variable switches off glibc's
#   dynamic mmap threshold, so every array above 128 kB (one float64 SMPL mesh is 165 kB) becomes a
#   fresh mmap and page faults: measured on align + eval, 3.5x the system time and 1.9x the wall
#   time of the same work without it.
# - Housekeeping for a dashboard rotavat does not open: Dask's defaults wake every process every
#   20 ms (event-loop tick) and sample each worker's stack every 10 ms (profiler). An idle
#   2-worker LocalCluster measured 24% of a core (driver 10%, each worker 7%); with these, 4%.
#   On 2 cores that is CPU taken from the workers.
LOCAL_CLUSTER_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.tick.limit": "30s",
    "distributed.admin.system-monitor.interval": "5s",
}


def local_cluster(workers: int) -> Any:
    """A dask.distributed LocalCluster on loopback: ``workers`` processes of one thread, rotavat's configuration."""
    import dask  # lazy: optional extra rotavat[dask]
    import distributed  # lazy: optional extra rotavat[dask]

    with dask.config.set(LOCAL_CLUSTER_CONFIG):
        return distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                                        dashboard_address=None, silence_logs=logging.ERROR)


def make_executor(options: BatchOptions, n_tasks: int) -> Any:
    """The executor for ``options`` (a usage error if it cannot be had): at most one local worker per
    core and per task (``--jobs 10000`` starts no more than that; an existing Dask cluster keeps its size)."""
    jobs = cap_workers(options.jobs, n_tasks)
    if options.executor == "dask":
        return _DaskExecutor(options.scheduler, jobs)
    return InlineExecutor() if jobs == 1 else _PoolExecutor(jobs)

