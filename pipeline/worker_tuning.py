"""Settings of a worker process: glibc's allocator, BLAS threads, the garbage collector.

Run by :func:`run_task` around every task of the local process pool and of Dask workers; a single
job runs in the coordinator with the interpreter's defaults.

Allocator.
A task allocates and drops arrays of tens to hundreds of MB (a 24 h, 100 Hz day is 8.64 M samples:
69 MB per float64 column). glibc serves each allocation above its mmap threshold with a fresh
``mmap`` and returns it with ``munmap`` when freed, so every such array costs a page fault and a
zeroed page per 4 KiB touched (and, with the page cache full, reclaim); its adaptive threshold tops
out at 32 MiB, below these arrays. Measured on 24 h chest days (``classify_recording``) in a pool of
2 workers: 3.85 s per day, 1.05 s of it kernel time, by default; 2.9-3.0 s, 0.25 s kernel time, with
the heap-only settings below (docs/operations.md: the whole night).

:func:`tune_allocator` (run by :func:`run_task` before a worker process's first task) serves all
allocations from the heap (``M_MMAP_MAX = 0``), stops glibc trimming it on every free
(``M_TRIM_THRESHOLD``), and keeps one heap for all threads (``M_ARENA_MAX = 1``), so freed arrays are
reused in place whichever thread (Arrow's and the MCAP reader's I/O threads) allocated them. One arena is
what keeps the untrimmed heap small: with glibc's default of one arena per thread a worker's heaps grew to
1.9 GB over a night, with one 1.36-1.39 GB (d7f8942's 20-participant night; 1.2 GB since). Memory is not given back between tasks: on
the reference machine (a VM whose free memory returns to its host seconds after it is freed) re-touching
returned pages costs ~2-3 CPU-s per GB in the kernel, and a ``malloc_trim`` after every task cost the night
~10 % of its time. :func:`release_memory` (after every task) gives the free pages back only when the
worker holds more than :data:`RELEASE_ABOVE_BYTES`, so a fragmented heap cannot carry more than that into the
next task. Elsewhere (macOS, musl) all of this does nothing.

BLAS threads. A worker runs one task on one core beside the other workers, so OpenBLAS's own thread
pools (NumPy's and SciPy's, one thread per core each) only spin-wait after every BLAS call, taking
the core from the other worker. :func:`single_thread_env` sets ``OPENBLAS_NUM_THREADS=1`` (and the OpenMP
and MKL equivalents) as a pool worker starts, as Dask's nanny does for its workers, so a BLAS library loaded
later in the worker's life starts with one thread; :func:`limit_blas_threads` (``threadpoolctl``) limits the
ones already loaded. The limit alone missed SciPy's own OpenBLAS, which the activity and orientation stages
load only after the worker's first (ingest) task: its second thread spun after every ``lstsq`` and ``eigh``,
~1.5 CPU-s of a 20-participant night (``perf``). The Dask and local engines' warehouses are compared
identical by ``stridelab bench pipeline --compare-engines``.

Garbage collector. After each task the objects still alive (modules, compiled kernels, caches) are
collected once and frozen (:func:`gc.freeze`), so the collector's full passes during the next task
traverse only what that task allocates, not the hundreds of thousands of objects numba, SciPy and
DuckDB keep. They are unfrozen at exit, so the interpreter's shutdown still finalises them (DuckDB's
nanobind types report frozen ones as leaked).
"""
from __future__ import annotations

import atexit
import ctypes
import gc
import os
import sys
from typing import Callable

M_TRIM_THRESHOLD = -1   # <malloc.h>
M_MMAP_MAX = -4
M_ARENA_MAX = -8
TRIM_THRESHOLD_BYTES = 2_000_000_000    # an int for mallopt; above any single task's free memory
#: a worker holding more than this (resident) after a task gives its heap's free pages back (issue 19's
#: memory budget per worker)
RELEASE_ABOVE_BYTES = 1_500_000_000

_libc = None
_tuned = False


def _glibc():
    global _libc
    if _libc is None:
        _libc = False
        if sys.platform.startswith("linux"):
            try:
                lib = ctypes.CDLL(None)
                lib.mallopt, lib.malloc_trim     # noqa: B018 - both exist only in glibc
                _libc = lib
            except (OSError, AttributeError):
                pass
    return _libc


def tune_allocator() -> bool:
    """Heap-only allocation in one arena without trimming in this process; True when the settings took
    effect."""
    lib = _glibc()
    if not lib:
        return False
    return (bool(lib.mallopt(M_MMAP_MAX, 0)) and bool(lib.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
            and bool(lib.mallopt(M_ARENA_MAX, 1)))


def resident_bytes() -> int | None:
    """This process's resident set size (Linux ``/proc/self/statm``), None where unavailable."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def release_memory(above: int = RELEASE_ABOVE_BYTES) -> bool:
    """Give the heap's free pages back to the operating system when this process holds more than ``above``
    bytes; True when it did."""
    lib = _glibc()
    if not lib:
        return False
    rss = resident_bytes()
    if rss is not None and rss <= above:
        return False
    lib.malloc_trim(0)
    return True


#: environment variables read by BLAS and OpenMP libraries as they load (set by :func:`single_thread_env`)
SINGLE_THREAD_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def single_thread_env() -> None:
    """One thread for every BLAS/OpenMP library this process loads from now on (see the module docstring)."""
    os.environ.update(SINGLE_THREAD_ENV)


def limit_blas_threads() -> None:
    """One thread for every BLAS/OpenMP library loaded in this process."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:                 # pragma: no cover - a dependency of scikit-learn
        return
    threadpool_limits(1)


def settle_objects() -> None:
    """Collect what the last task left and freeze the survivors out of later collections."""
    gc.collect()
    gc.freeze()


def run_task(fn: Callable, *args):
    """``fn(*args)`` in a worker process: allocator and BLAS threads set before the first task, and after
    each task (also when it raises) its garbage collected, and its freed memory given back when the worker
    holds more than :data:`RELEASE_ABOVE_BYTES`."""
    global _tuned
    if not _tuned:
        tune_allocator()
        single_thread_env()
        limit_blas_threads()
        atexit.register(gc.unfreeze)
        _tuned = True
    try:
        return fn(*args)
    finally:
        settle_objects()
        release_memory()
