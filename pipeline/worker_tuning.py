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
the settings below (docs/operations.md: the whole night, and the variant without the trim).

:func:`tune_allocator` (run by :func:`run_task` before a worker process's first task) serves all
allocations from the heap (``M_MMAP_MAX = 0``) and stops glibc trimming it on every free (``M_TRIM_THRESHOLD``), so freed
arrays are reused in place. :func:`release_memory` (after every task) returns the free pages to the
operating system with ``malloc_trim(0)``, so what a worker holds between tasks is only what it
uses, and one task's peak is not carried into the next. Elsewhere (macOS, musl) both do nothing.

BLAS threads. A worker runs one task on one core beside the other workers, so OpenBLAS's own thread
pools (NumPy's and SciPy's, one thread per core each) only spin-wait after every BLAS call, taking
the core from the other worker. They are limited to one thread (``threadpoolctl``), as Dask's nanny
does for its workers with ``OPENBLAS_NUM_THREADS=1``; the Dask and local engines' warehouses are
compared identical by ``stridelab bench pipeline --compare-engines``.

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
import sys
from typing import Callable

M_TRIM_THRESHOLD = -1   # <malloc.h>
M_MMAP_MAX = -4
TRIM_THRESHOLD_BYTES = 2_000_000_000    # an int for mallopt; above any single task's free memory

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
    """Heap-only allocation without trimming in this process; True when the settings took effect."""
    lib = _glibc()
    if not lib:
        return False
    return bool(lib.mallopt(M_MMAP_MAX, 0)) and bool(lib.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))


def release_memory() -> None:
    """Give the heap's free pages back to the operating system."""
    lib = _glibc()
    if lib:
        lib.malloc_trim(0)


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
    each task (also when it raises) its garbage collected and its freed memory given back."""
    global _tuned
    if not _tuned:
        tune_allocator()
        limit_blas_threads()
        atexit.register(gc.unfreeze)
        _tuned = True
    try:
        return fn(*args)
    finally:
        settle_objects()
        release_memory()
