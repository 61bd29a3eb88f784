"""Worker processes of the local engine run their tasks with the tuned allocator, one BLAS thread, a frozen
garbage-collector generation, keep their freed memory for the next task unless they hold more than the budget
(pipeline/worker_tuning.py)."""
from __future__ import annotations

import gc
import multiprocessing as mp
import subprocess
import sys
import threading
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from stridelab.pipeline.engines import LocalEngine
from stridelab.pipeline.worker_tuning import _glibc, release_memory, run_task

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
    if kind == "thread_alloc":            # where a large array allocated by another thread lives
        out = []
        t = threading.Thread(target=lambda: out.append(_in_heap(np.ones(BIG // 8).ctypes.data)))
        t.start()
        t.join()
        return out[0]
    if kind == "release":                 # the budget exceeded: free pages go back
        release_memory(above=0)
        return _rss_mb()
    if kind == "blas":
        from threadpoolctl import threadpool_info
        return sorted({d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"})
    if kind == "blas_late":               # a BLAS library first loaded by a later task (SciPy's own OpenBLAS)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import threadpool_info
        return {d["filepath"]: d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"}
    if kind == "ingest_loaded":           # the worker's start imported the ingest modules (this module does not)
        return "stridelab.pipeline.ingest" in sys.modules
    if kind == "ready":                   # ... and what the first task would import or load before its first byte
        from numba.core.registry import cpu_target
        return ("stridelab.pipeline.ingest" in sys.modules, "pandas" in sys.modules,
                len(cpu_target.target_context._registries) > 1)
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


@pytest.mark.slow
def test_local_engine_workers_serve_large_arrays_from_the_heap():
    out = {}
    eng = LocalEngine(2)
    try:
        eng.run_all(probe, [("alloc",), ("alloc",)], lambda it, r: out.setdefault(len(out), r))
    finally:
        eng.close()
    assert out == {0: True, 1: True}        # M_MMAP_MAX = 0: no mmap of their own


@pytest.mark.slow
def test_local_engine_starts_its_workers_before_the_first_task():
    """``start`` spawns every worker at once (a pool spawns one per task submitted while none is idle), and each
    imports the ingest modules as it starts, so the first file does not wait for them."""
    out = []
    eng = LocalEngine(2)
    try:
        eng.start()
        assert len(eng.pool._processes) == 2
        eng.run_all(probe, [("ingest_loaded",)], lambda it, r: out.append(r))
    finally:
        eng.close()
    assert out == [True]


@pytest.mark.slow
def test_workers_started_early_are_taken_over_by_the_run_and_ready():
    """``start_workers_early`` (the CLI's ``run`` and the pipeline bench, before they import the runner) starts
    the pool; the next ``make_engine`` of the same size takes it over, with its workers already spawned and past
    the imports and registry loads of a first task."""
    from stridelab.pipeline import engines
    assert engines._early is None
    engines.start_workers_early("local", 2)
    early = engines._early
    out = []
    try:
        assert early is not None and len(early.pool._processes) == 2
        eng = engines.make_engine("local", 2)
        assert eng is early and engines._early is None
        eng.run_all(probe, [("ready",)], lambda it, r: out.append(r))
    finally:
        early.close()
        engines._early = None
    assert out == [(True, True, True)]
    engines.start_workers_early("local", 1)          # one job runs in the coordinator: nothing to start
    engines.start_workers_early("dask", 2)
    assert engines._early is None


def test_the_engines_module_starts_workers_before_the_heavy_imports():
    """Starting the workers early only helps if importing ``stridelab.pipeline.engines`` itself is light."""
    code = ("import sys, stridelab.pipeline.engines; "
            "print(sorted(m for m in ('numpy', 'duckdb', 'pyarrow', 'pandas', 'numba') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]"


class _MarksTeardown:
    """Writes its file when the interpreter's teardown clears the module that holds it."""

    def __init__(self, path: str):
        self.path = path

    def __del__(self, _open=open):           # builtins may be gone when the teardown gets here
        with _open(self.path, "w") as f:
            f.write("torn down")


_held = []


def _hold_until_teardown(path: str) -> bool:
    _held.append(_MarksTeardown(path))
    return True


@pytest.mark.slow
def test_local_engine_workers_exit_without_the_interpreter_teardown(tmp_path):
    """A pool worker leaves by ``os._exit`` from an exit handler (pipeline/engines.py ``_exit_now``): an object
    a task left in a module global is never finalised, and ``close`` does not wait for a teardown. Checked by
    its effect, not by time: in a plain spawned worker the same object is finalised at exit."""
    out = []
    eng = LocalEngine(2)
    try:
        eng.run_all(_hold_until_teardown, [(str(tmp_path / "engine"),)], lambda it, r: out.append(r))
    finally:
        eng.close()
    assert out == [True] and not (tmp_path / "engine").exists()
    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
        assert pool.submit(_hold_until_teardown, str(tmp_path / "plain")).result()
    assert (tmp_path / "plain").read_text() == "torn down"


@pytest.mark.slow
def test_dask_workers_task_thread_serves_large_arrays_from_the_heap():
    """A Dask worker's task thread exists before its first task: only MALLOC_ARENA_MAX at the worker's
    start keeps it on the main heap (pipeline/engines.py)."""
    from stridelab.pipeline.engines import DaskEngine
    out = []
    eng = DaskEngine(1)
    try:
        eng.run_all(probe, [("alloc",), ("alloc",)], lambda it, r: out.append(r))
    finally:
        eng.close()
    assert out == [True, True]


def test_without_tuning_a_large_array_is_a_separate_mapping():
    """The control: in a plain process glibc maps an array of this size on its own."""
    a = np.ones(BIG // 8)
    assert not _in_heap(a.ctypes.data)


@pytest.mark.slow
def test_a_blas_library_loaded_after_the_first_task_has_one_thread_too():
    """SciPy loads its own OpenBLAS only when a stage imports scipy.linalg, after the limit of the first task."""
    for probes in (_one_worker("rss", "blas_late"), _local_engine_worker("rss", "blas_late")):
        libs = probes[1]
        assert len(libs) >= 1
        assert set(libs.values()) == {1}, libs


def _local_engine_worker(*kinds):
    """``probe(kind)`` for each kind in turn in the local engine's pool (its workers' own start)."""
    out = []
    eng = LocalEngine(2)
    try:
        for k in kinds:
            eng.run_all(probe, [(k,)], lambda it, r: out.append(r))
    finally:
        eng.close()
    return out


def test_worker_has_one_blas_thread_and_freezes_survivors_after_a_task():
    blas, first, second = _one_worker("blas", "frozen", "frozen")
    assert blas == [1]
    assert first > 0 and second >= first    # frozen after the first task: modules, kernels, caches


def test_worker_threads_share_the_heap():
    assert _one_worker("thread_alloc") == [True]    # M_ARENA_MAX = 1: no per-thread arena of its own


@pytest.mark.slow
def test_worker_keeps_freed_memory_below_the_budget_and_gives_it_back_above():
    held, after, released = _one_worker("touch", "rss", "release")
    assert held - after < 100, (held, after)        # 400 MB freed, kept for the next task (< 1.5 GB held)
    assert after - released > 300, (after, released)   # over the budget: malloc_trim gave them back
