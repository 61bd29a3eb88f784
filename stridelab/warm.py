"""``stridelab warm-kernels``: compile every numba kernel the pipeline uses, once, at install time.

``make install`` runs it after ``pip install``: a tiny simulated study (one participant's calibration and
walking trials and the first free-living hour from 07:00, with getting up and sit-stand transitions, with the opt-in free-living orientation asked
for) goes through ingest and every stage in this process, so each kernel is compiled for the argument types
the pipeline really passes and written to the installation's shared cache (``estimators/_numba_cache.py``).
Every later process (``make demo``, the nightly run's pool or Dask workers) loads the machine code from there
instead of compiling it on the user's clock. Kernels only benches call (PSO tuning, the comparison filters)
stay lazily compiled; the command lists how many.

A finished warm-up leaves ``warm-kernels.json`` in the cache directory with a fingerprint of the sources
(path, size, mtime of every module of the folders that define kernels) and numba's version, and removes the
cache directories of other sources:
:func:`is_warm` tells ``stridelab demo`` whether it has to run the warm-up itself (``make demo`` installs
the packages, then the demo compiles the kernels in a second process while it simulates the study, before
the pipeline runs; see ``stridelab/cli.py``).
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

MARKER = "warm-kernels.json"


def kernel_stats() -> dict:
    """Every numba dispatcher of the project's loaded modules: signatures compiled in this process (cache
    misses), loaded from the cache (hits), and kernels with no machine code in this process (never called:
    bench-only kernels, and helpers already compiled into a cached caller)."""
    from numba.core.registry import CPUDispatcher
    compiled = loaded = unused = 0
    names_compiled = []
    seen = set()
    for name, mod in list(sys.modules.items()):
        if mod is None or not (name == "stridelab" or name.startswith("stridelab.")):
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
    from stridelab.pipeline import config, runner
    from stridelab.pipeline.formats.mcap_write import write_recording
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.simulator import simulate_chest_day, simulate_lab_session, study_participants
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
    import duckdb
    with duckdb.connect(str(workdir / "warehouse" / "catalog.duckdb"), read_only=True) as con:
        ran = con.execute("SELECT stage, status, count(*) FROM stage_runs WHERE run_id = ? GROUP BY ALL ORDER BY ALL",
                          [summary.run_id]).fetchall()
    return {**kernel_stats(), "stage_runs": summary.stage_runs,
            "stage_status": {f"{stage}:{status}": n for stage, status, n in ran}}


def fingerprint(root: Path | None = None) -> str:
    """What numba's cache validity depends on here: the kernel modules' paths, sizes and mtimes
    (:func:`stridelab.estimators._numba_cache.sources_key`, which also names the cache directory), numba's and
    Python's versions. ``root`` holds the layers' folders: the repository in a checkout, ``site-packages/stridelab``
    once installed (where ``stridelab.estimators`` is found)."""
    import numba
    from stridelab.estimators._numba_cache import sources_key
    return hashlib.sha256(f"{numba.__version__} {sys.version} {sources_key(root)}".encode()).hexdigest()


def prune_other_sources() -> list[str]:
    """Remove the cache directories of other kernel sources (older checkouts, earlier versions) beside this one."""
    import shutil
    from stridelab.estimators._numba_cache import CACHE_DIR
    from stridelab.estimators._numba_cache import venv_cache_dir
    here = venv_cache_dir()
    if here is None or CACHE_DIR != str(here):
        return []
    removed = []
    for d in here.parent.iterdir():          # directories of other sources; files of the unkeyed layout before
        if d == here:
            continue
        if d.is_dir():
            shutil.rmtree(d, ignore_errors=True)
        else:
            d.unlink(missing_ok=True)
        removed.append(d.name)
    return removed


def _marker() -> Path | None:
    from stridelab.estimators._numba_cache import CACHE_DIR
    return Path(CACHE_DIR) / MARKER if CACHE_DIR else None


def is_warm() -> bool:
    """True when ``stridelab warm-kernels`` finished in this installation's cache for the current sources;
    also True outside a venv (numba's default cache: nothing to warm for the demo)."""
    m = _marker()
    if m is None:
        return True
    try:
        return json.loads(m.read_text())["fingerprint"] == fingerprint()
    except (OSError, ValueError, KeyError, TypeError):
        return False


def write_marker(signatures: int) -> None:
    """Record a finished warm-up for the current sources (atomically: temporary file + rename)."""
    m = _marker()
    if m is None:
        return
    tmp_m = m.with_name(f".{m.name}.tmp-{os.getpid()}")
    tmp_m.write_text(json.dumps({"fingerprint": fingerprint(), "signatures": int(signatures)}))
    os.replace(tmp_m, m)


def warm(**kw) -> dict:
    from stridelab.estimators._numba_cache import CACHE_DIR
    with tempfile.TemporaryDirectory(prefix="stridelab-warm-") as tmp:
        out = run_small_study(Path(tmp), **kw)
    write_marker(out["signatures_compiled"] + out["signatures_from_cache"])
    prune_other_sources()
    return {"cache_dir": CACHE_DIR or "numba default (__pycache__ beside each source file)", **out}
