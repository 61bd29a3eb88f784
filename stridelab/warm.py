"""``stridelab warm-kernels``: compile every numba kernel the pipeline uses, once, at install time.

``make install`` runs it after ``pip install``: a tiny simulated study (one participant's calibration and
walking trials and the first free-living hour from 07:00, with getting up and sit-stand transitions, with the opt-in free-living orientation asked
for) goes through ingest and every stage in this process, so each kernel is compiled for the argument types
the pipeline really passes and written to the installation's shared cache (``estimators/_numba_cache.py``).
Every later process (``make demo``, the nightly run's pool or Dask workers) loads the machine code from there
instead of compiling it on the user's clock. Kernels only benches call (PSO tuning, the comparison filters)
stay lazily compiled; the command lists how many.
"""
from __future__ import annotations

import os
import sys
import tempfile
from dataclasses import replace
from pathlib import Path


def kernel_stats() -> dict:
    """Every numba dispatcher of the project's loaded modules: signatures compiled in this process (cache
    misses), loaded from the cache (hits), and kernels with no machine code in this process (never called:
    bench-only kernels, and helpers already compiled into a cached caller)."""
    from numba.core.registry import CPUDispatcher
    compiled = loaded = unused = 0
    names_compiled = []
    seen = set()
    for name, mod in list(sys.modules.items()):
        if mod is None or not name.split(".")[0] in ("estimators", "pipeline", "warehouse", "studies", "validation", "reports", "stridelab"):
            continue
        for obj in list(vars(mod).values()):
            if not isinstance(obj, CPUDispatcher) or id(obj) in seen:
                continue
            seen.add(id(obj))
            st = obj.stats
            miss, hit = sum(st.cache_misses.values()), sum(st.cache_hits.values())
            compiled += miss
            loaded += hit
            if miss:
                names_compiled.append(f"{obj.py_func.__module__}.{obj.py_func.__name__}")
            if not obj.signatures:
                unused += 1
    return {"kernels": len(seen), "signatures_compiled": compiled, "signatures_from_cache": loaded,
            "kernels_not_called": unused, "compiled": sorted(names_compiled)}


def run_small_study(workdir: Path, *, index: int = 0, hours: float = 1.0, start_local: str = "07:00") -> dict:
    """Simulate one participant of the demo study (lab session + ``hours`` of free-living chest data) and run
    ingest and every stage on it in this process; returns :func:`kernel_stats` afterwards."""
    from pipeline import config, runner
    from pipeline.formats.mcap_write import write_recording
    from studies.manifest import DEFAULT_MANIFEST, load_manifest
    from validation.simulator import simulate_chest_day, simulate_lab_session, study_participants
    m = load_manifest(DEFAULT_MANIFEST)
    m = replace(m, name="warm-kernels", lab=replace(m.lab, walking_trials=1),
                free_living=replace(m.free_living, hours=hours, start_local=start_local))
    p = study_participants(m, index + 1)[index]
    inbox = workdir / "inbox"
    inbox.mkdir(parents=True)
    files = [write_recording(rec, inbox / f"{rec.name}.mcap") for rec, _ in simulate_lab_session(m, p, index)]
    rec, _ = simulate_chest_day(m, p, index)
    files.append(write_recording(rec, inbox / f"{rec.name}.mcap"))
    studies = workdir / "studies"
    (studies / m.name).mkdir(parents=True)
    (studies / m.name / "study.toml").write_text("[compute.orientation]\nfree_living = true\n")
    old = os.environ.get("STRIDELAB_STUDIES")
    os.environ["STRIDELAB_STUDIES"] = str(studies)
    config.study_manifest.cache_clear()
    try:
        summary = runner.run(workdir / "warehouse", None, files=files, command="warm-kernels")
    finally:
        if old is None:
            os.environ.pop("STRIDELAB_STUDIES", None)
        else:
            os.environ["STRIDELAB_STUDIES"] = old
        config.study_manifest.cache_clear()
    if summary.failed or summary.quarantined:
        raise RuntimeError(f"warm-up study failed: {summary.failed or summary.quarantined}")
    return {**kernel_stats(), "stage_runs": summary.stage_runs}


def warm(**kw) -> dict:
    from estimators._numba_cache import CACHE_DIR
    with tempfile.TemporaryDirectory(prefix="stridelab-warm-") as tmp:
        out = run_small_study(Path(tmp), **kw)
    return {"cache_dir": CACHE_DIR or "numba default (__pycache__ beside each source file)", **out}
