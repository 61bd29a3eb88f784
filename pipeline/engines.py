"""Execution engines for the runner: where per-file and per-session tasks run.

The coordinator (the process holding the run lock) submits tasks and commits their results one at
a time as they complete. Tasks are pure with respect to the catalog: they read series files, write
immutable Parquet files and return rows, so a task that dies can simply be run again.

- ``local``: in-process for one job, else a process pool; a worker that dies (OOM killer, kill -9)
  breaks the pool, which is rebuilt and the unfinished tasks resubmitted (at most ``max_attempts``).
- ``dask``: the same tasks on Dask distributed, a LocalCluster by default or ``--scheduler
  ADDRESS``; the warehouse directory must be on a filesystem shared with the workers.

Workers of both engines die with the coordinator (``pipeline/lifeline.py``): a coordinator killed
by the OOM killer leaves no worker behind. Their tasks run through ``worker_tuning.run_task``
(heap allocation without mmap churn, free memory returned after each task); a single job runs in
the coordinator with the allocator's defaults.
"""
from __future__ import annotations

import atexit
import multiprocessing as mp
import os
import sys
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Iterable

from stridelab.pipeline.lifeline import COORDINATOR_ENV, die_with_parent
from stridelab.pipeline.worker_tuning import run_task, single_thread_env


class TaskLost(RuntimeError):
    """A task whose worker died more than the allowed number of times."""


def _start_worker(parent_pid: int) -> None:
    """A pool worker's start: die with the coordinator (kill -9, OOM killer) instead of lingering, one BLAS
    thread in every library it loads (``worker_tuning.single_thread_env``), end without the interpreter's
    teardown (:func:`_exit_now`), then get ready for the first task (:func:`_get_ready`)."""
    die_with_parent(parent_pid)
    single_thread_env()
    atexit.register(_exit_now)
    try:
        _get_ready()
    except Exception:  # noqa: BLE001 - the first task meets the same problem and reports it as its own
        pass


def _get_ready() -> None:
    """What a worker's first task would otherwise pay before its first byte (~0.9 s of a lab file's 0.06 s task,
    measured on a fresh worker): the ingest's modules (pyarrow, the MCAP reader), pandas (pyarrow imports it on
    its first ``pa.array`` of a NumPy array, to ask whether it is categorical) and numba's registries of
    NumPy implementations (``refresh``: loaded once per process, before the first kernel comes from the cache).
    Done here, it overlaps the coordinator's own start (:func:`start_workers_early`)."""
    import stridelab.pipeline.ingest  # noqa: F401
    try:
        import pandas  # noqa: F401
    except ImportError:         # pragma: no cover - a dependency of the dashboard; pyarrow works without it
        pass
    from numba.core.registry import cpu_target
    cpu_target.target_context.refresh()


def _exit_now() -> None:
    """A pool worker's exit: leave at once. Registered as the worker starts, it runs after the exit handlers of
    what its tasks imported (atexit is last-in, first-out) and before multiprocessing's own and the
    interpreter's teardown. That teardown, for a worker that ran stages (a million objects of numba, SciPy,
    pyarrow, DuckDB to collect, modules to clear), took 0.25-0.5 s, and ``close`` waits for it at the end of
    every run. A worker needs none of it: every task's files are committed or removed before its result is
    returned, and results go back through a queue written synchronously."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _ready() -> None:
    return None


class LocalEngine:
    name = "local"

    def __init__(self, jobs: int, max_attempts: int = 3):
        self.jobs = max(1, int(jobs))
        self.max_attempts = max_attempts
        self.pool: ProcessPoolExecutor | None = None

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(self.jobs, mp_context=mp.get_context("spawn"), initializer=_start_worker,
                                   initargs=(os.getpid(),))

    def start(self) -> None:
        """Start the worker processes now (a pool starts one per task submitted while none is idle), so that they
        start and import while the coordinator opens the warehouse (``runner.run``)."""
        if self.jobs > 1 and self.pool is None:
            self.pool = self._new_pool()
            for _ in range(self.jobs):
                self.pool.submit(_ready)

    def run_all(self, fn: Callable, items: Iterable, on_done: Callable) -> None:
        """Call ``fn(*item)`` for each item; ``on_done(item, result_or_exception)`` runs in the coordinator.

        ``items`` may be a generator: the first items run while it produces the next ones (the runner builds
        a stage task's inputs from the catalog, ~10 ms each, while the workers already compute), and it is
        drained before the first ``on_done``, so producing an item never sees a result of the same call."""
        if self.jobs == 1:
            for it in list(items):
                try:
                    r = fn(*it)
                except Exception as e:  # noqa: BLE001 - reported per item
                    r = e
                on_done(it, r)
            return
        if self.pool is None:
            self.pool = self._new_pool()
        source = iter(items)
        got: list = []                  # items taken from ``source``, by index
        attempts: list[int] = []
        queue: list[int] = []           # indices to submit (retries first)
        held: list[tuple[int, object]] = []     # results that arrived while ``source`` was not yet drained
        drained = False
        pending: dict[Future, int] = {}

        def take() -> bool:
            nonlocal drained
            if drained:
                return False
            try:
                it = next(source)
            except StopIteration:
                drained = True
                return False
            got.append(it)
            attempts.append(0)
            queue.append(len(got) - 1)
            return True

        while queue or pending or held or not drained:
            while len(pending) < 2 * self.jobs and (queue or take()):
                i = queue.pop(0)
                attempts[i] += 1
                try:
                    pending[self.pool.submit(run_task, fn, *got[i])] = i
                except BrokenProcessPool:
                    queue.insert(0, i)
                    attempts[i] -= 1
                    self._rebuild(pending, queue)
            if not drained:
                take()                  # the next item while the workers run; results are collected meanwhile
                done = {f for f in pending if f.done()}
            elif held or not pending:
                done = set()
            else:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
            broken = False
            for fut in done:
                i = pending.pop(fut)
                try:
                    r = fut.result()
                except BrokenProcessPool:
                    broken = True
                    if attempts[i] < self.max_attempts:
                        queue.insert(0, i)
                        continue
                    r = TaskLost(f"worker process died {attempts[i]} times while running this task")
                except Exception as e:  # noqa: BLE001
                    r = e
                held.append((i, r))
            if drained:
                for i, r in held:
                    on_done(got[i], r)
                held.clear()
            if broken:
                self._rebuild(pending, queue)

    def _rebuild(self, pending: dict, queue: list) -> None:
        """A dead worker poisons the whole pool: requeue everything in flight on a fresh pool."""
        for fut, i in list(pending.items()):
            queue.insert(0, i)
        pending.clear()
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = self._new_pool()

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None


class DaskEngine:
    name = "dask"

    def __init__(self, jobs: int, scheduler: str | None = None, max_attempts: int = 3):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:  # pragma: no cover - dask is a dependency
            raise RuntimeError("--engine dask needs dask[distributed]: pip install 'dask[distributed]'") from None
        import dask
        # Dask's nanny spawns workers with MALLOC_TRIM_THRESHOLD_=65536 (to hand freed memory back to the OS
        # at once). Setting it also freezes glibc's mmap threshold at 128 KiB, so every array the decoders
        # and the stages allocate and drop is a fresh mmap: page faults and zeroing on each. A 20-participant
        # night cost 273 worker CPU-s with it and 226 without (ingest phase 90 s and 64 s). The workers keep
        # glibc's adaptive defaults, as the local engine's do; the thread settings stay.
        environ = {k: v for k, v in (dask.config.get("distributed.nanny.pre-spawn-environ") or {}).items()
                   if k != "MALLOC_TRIM_THRESHOLD_"}
        # A worker runs its tasks in a thread of its own, created before the first task could set glibc's
        # M_ARENA_MAX (pipeline/worker_tuning.py), so it had a malloc arena of its own, whose freed arrays went
        # back to the kernel: ~130,000-160,000 page faults and 1.1-2.6 s of kernel time per 24 h activity day
        # (0.01 s in a local-engine worker). Read by glibc at the worker's start, before any thread exists:
        environ["MALLOC_ARENA_MAX"] = "1"
        dask.config.set({"distributed.scheduler.allowed-failures": max_attempts - 1,
                         "distributed.worker.daemon": False,
                         "distributed.nanny.pre-spawn-environ": environ,
                         # the statistical profiler samples every thread's stack every 10 ms, holding the
                         # GIL, and an ingest runs six threads: 26 worker CPU-s of the same night
                         "distributed.worker.profile.enabled": False,
                         # health checks of the event loops at a pace that suits tasks of seconds
                         "distributed.admin.tick.interval": "200ms",
                         "distributed.admin.system-monitor.interval": "2s",
                         "distributed.worker.memory.monitor-interval": "1s"})
        self.cluster = None
        if scheduler:
            self.client = Client(scheduler, timeout="30s")
        else:
            # the preload makes each worker process die with this coordinator (pipeline/lifeline.py)
            os.environ[COORDINATOR_ENV] = str(os.getpid())
            self.cluster = LocalCluster(n_workers=max(1, jobs), threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=40, preload=["stridelab.pipeline.lifeline"])
            self.client = Client(self.cluster)
        self.max_attempts = max_attempts

    def run_all(self, fn: Callable, items: Iterable, on_done: Callable) -> None:
        from dask.distributed import as_completed
        # each item submitted as it is produced (the cluster starts on it), results read once all are
        # submitted: the same contract as LocalEngine.run_all
        got, futs = [], {}
        for it in items:
            futs[self.client.submit(run_task, fn, *it, pure=False, retries=self.max_attempts - 1)] = len(got)
            got.append(it)
        if not got:
            return
        items = got
        for fut in as_completed(list(futs)):
            k = futs[fut]
            try:
                r = fut.result()
            except Exception as e:  # noqa: BLE001 - KilledWorker or the task's own error
                r = TaskLost(f"worker died repeatedly ({e})") if type(e).__name__ == "KilledWorker" else e
            on_done(items[k], r)
            fut.release()

    def start(self) -> None:
        """The cluster's workers started with it."""

    def close(self) -> None:
        if self.client is None:
            return
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        self.client = self.cluster = None


_early: LocalEngine | None = None


def start_workers_early(name: str, jobs: int, scheduler: str | None = None) -> None:
    """Start the local engine's worker processes now, before the caller imports the runner: a cold start of the
    coordinator (``from stridelab.pipeline import runner``: DuckDB, pyarrow, NumPy from the disk) takes ~0.8-1 s, and the
    workers start and get ready (:func:`_get_ready`) meanwhile instead of after it. The next
    ``make_engine(name, jobs)`` of this process takes them over; workers no run took over are shut down at exit.
    Does nothing for the Dask engine or a single job."""
    global _early
    if name == "local" and not scheduler and int(jobs) > 1 and _early is None:
        _early = LocalEngine(jobs)
        _early.start()
        atexit.register(_early.close)


def make_engine(name: str, jobs: int, scheduler: str | None = None):
    global _early
    if name == "local":
        if scheduler:
            raise ValueError("--scheduler needs --engine dask")
        if _early is not None and _early.jobs == max(1, int(jobs)):
            engine, _early = _early, None       # started by start_workers_early; its atexit close is harmless
            return engine
        return LocalEngine(jobs)
    if name == "dask":
        return DaskEngine(jobs, scheduler)
    raise ValueError(f"unknown engine '{name}' (local or dask)")
