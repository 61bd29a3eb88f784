"""Worker processes of the local engine run their tasks with the tuned allocator, one BLAS thread, a frozen
garbage-collector generation, and give freed memory back after each task (pipeline/worker_tuning.py)."""
from __future__ import annotations

import gc
import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from pipeline.engines import LocalEngine
from pipeline.worker_tuning import _glibc, run_task

pytestmark = pytest.mark.skipif(not (sys.platform.startswith("linux") and _glibc()),
                                reason="allocator settings exist only with glibc on Linux")

BIG = 64 << 20          # above glibc's default mmap threshold (128 KiB, adaptive up to 32 MiB)


def _in_heap(addr: int) -> bool:
    """Whether ``addr`` lies in this process's brk heap ([heap] in /proc/self/maps), not in its own mmap."""
    for line in open("/proc/self/maps"):
        if line.rstrip().endswith("[heap]"):
            lo, hi = (int(x, 16) for x in line.split()[0].split("-"))
            if lo <= addr < hi:
                return True
    return False


def _rss_mb() -> float:
    return next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmRSS:")) / 1024


def probe(kind: str):
    if kind == "alloc":                   # where a large array lives
        a = np.ones(BIG // 8)
        return _in_heap(a.ctypes.data)
    if kind == "blas":
        from threadpoolctl import threadpool_info
        return sorted({d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"})
    if kind == "touch":                   # touch 400 MB, free it, report the RSS while holding it
        a = np.ones(400 << 17)
        held = _rss_mb()
        del a
        return held
    if kind == "rss":
        return _rss_mb()
    if kind == "frozen":
        return gc.get_freeze_count()
    raise ValueError(kind)


def _one_worker(*kinds):
    """``probe(kind)`` for each kind in turn, in one spawned worker process, as the local engine runs tasks."""
    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
        return [pool.submit(run_task, probe, k).result() for k in kinds]


def test_local_engine_workers_serve_large_arrays_from_the_heap():
    out = {}
    eng = LocalEngine(2)
    try:
        eng.run_all(probe, [("alloc",), ("alloc",)], lambda it, r: out.setdefault(len(out), r))
    finally:
        eng.close()
    assert out == {0: True, 1: True}        # M_MMAP_MAX = 0: no mmap of their own


def test_without_tuning_a_large_array_is_a_separate_mapping():
    """The control: in a plain process glibc maps an array of this size on its own."""
    a = np.ones(BIG // 8)
    assert not _in_heap(a.ctypes.data)


def test_worker_has_one_blas_thread_and_freezes_survivors_after_a_task():
    blas, first, second = _one_worker("blas", "frozen", "frozen")
    assert blas == [1]
    assert first > 0 and second >= first    # frozen after the first task: modules, kernels, caches


def test_worker_gives_freed_memory_back_after_each_task():
    held, after = _one_worker("touch", "rss")
    assert held - after > 300, (held, after)    # the 400 MB went back although the trim threshold is 2 GB
