"""Warehouses for the dashboard tests, built the real way (MCAP files -> ingest through the runner).

* ``missing_wh``: a directory with nothing published;
* ``empty_wh``: a migrated warehouse whose snapshot has no data;
* ``ingested_wh``: recordings ingested by a real run (two participants, a quarantined file ``broken.mcap``, which
  the catalog and pages name ``rec-<keyed hash>.mcap``) with every registered stage run on its 6-s trials (too
  short for strides: the pages' "nothing yet" paths);
* ``demo_wh``: the demo study made small (2 participants, 6-min free-living days) simulated and run through
  every stage by the real pipeline — what a newcomer's ``stridelab demo`` shows;
* ``full_wh``: ``ingested_wh`` plus a free-living session and the results later stages will write
  (strides, calibration QC, joint-angle cycles, activity bouts with reference labels, accuracy,
  foot trajectories), added through the pipeline's writer by ``stridelab.validation.bench.dashboard``.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

import pytest

from stridelab.pipeline.formats.mcap_write import write_recording
from tests.browser import free_port, require_chromium, stop, wait_until_serving
from tests.corpus import T0_NS, small_recording
from stridelab.warehouse.catalog import Warehouse

APP = Path(__file__).resolve().parents[2] / "dashboard" / "app.py"
PAGES = ("overview", "accuracy", "participant", "programme", "activity", "runs")


@contextmanager
def serve_dashboard(wh: Path):
    """The app served by Streamlit on a free localhost port for ``wh`` (yields its URL); skips without Chromium
    or Playwright. The browser tests use it (test_browser.py, test_walking_home_browser.py, test_public_study.py)."""
    require_chromium()
    port = free_port()
    env = {**os.environ, "STRIDELAB_WAREHOUSE": str(wh)}
    proc = subprocess.Popen([sys.executable, "-m", "streamlit", "run", str(APP), "--server.port", str(port),
                             "--server.address", "localhost", "--server.headless", "true",
                             "--browser.gatherUsageStats", "false", "--server.fileWatcherType", "none",
                             "--", "--warehouse", str(wh)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    url = f"http://localhost:{port}"
    try:
        wait_until_serving(proc, f"{url}/_stcore/health", "streamlit")
        yield url
    finally:
        stop(proc, 10)


def _ingest(root: Path, inbox: Path) -> None:
    from stridelab.pipeline import runner
    inbox.mkdir(parents=True, exist_ok=True)
    files = []
    for i, (pid, ses) in enumerate((("P001", "S01"), ("P001", "S02"), ("P002", "S03"))):
        rec = small_recording(seconds=6.0, seed=i, session=ses, participant=pid, trial=f"walk-{i}")
        files.append(write_recording(rec, inbox / f"{pid}_{ses}.mcap"))
    bad = inbox / "broken.mcap"
    bad.write_bytes(files[0].read_bytes()[:500])
    files.append(bad)
    runner.run(root, None, files=files, stages=True, command="run")     # ingest + the stages that exist


@pytest.fixture(scope="session")
def missing_wh(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("missing") / "warehouse"


@pytest.fixture(scope="session")
def empty_wh(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("empty") / "warehouse"
    with Warehouse.open(root) as wh:
        wh.publish_snapshot()
    return root


@pytest.fixture(scope="session")
def ingested_wh(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("ingested")
    _ingest(base / "warehouse", base / "inbox")
    return base / "warehouse"


@pytest.fixture(scope="session")
def full_wh(tmp_path_factory, ingested_wh) -> Path:
    from stridelab.validation.bench.dashboard import add_synthetic_results
    root = tmp_path_factory.mktemp("full") / "warehouse"
    shutil.copytree(ingested_wh, root)
    day = 86_400 * 10**9
    with Warehouse.open(root) as wh:
        with wh.transaction() as con:
            start = T0_NS + 2 * day
            con.execute("INSERT INTO sessions VALUES ('S09', 'testing', 'P001', 'free_living', 'free-living', "
                        "'Europe/Zurich', ?, ?)", [start, start + 9 * day])
            wh.insert("recordings", [{"content_hash": "f" * 64, "file_name": "P001_home.mcap", "status": "ingested",
                                      "session_id": "S09", "trial": "free-living", "start_ns": start,
                                      "end_ns": start + 9 * day, "n_samples": 1, "ingested_at": datetime(2026, 3, 20)}])
            rows = con.execute("SELECT * FROM sessions").df().to_dict("records")
            add_synthetic_results(wh, [dict(r, content_hash="f" * 64) for r in rows], seed=1)
            wh.insert("stage_runs", [{"run_id": "r1", "session_id": "S03", "stage": "gait", "stage_version": "1",
                                      "status": "failed", "started_at": datetime(2026, 3, 20),
                                      "error": "ValueError: no stance phase detected"}])
        wh.publish_snapshot()
    return root


@pytest.fixture(scope="session")
def demo_wh(tmp_path_factory) -> Path:
    from stridelab.pipeline import runner
    from stridelab.validation.simulate import simulate_to_dir
    base = tmp_path_factory.mktemp("demo")
    simulate_to_dir(base / "inbox", participants=2, hours=0.1, jobs=2)
    summary = runner.run(base / "warehouse", base / "inbox", jobs=2, command="run")
    assert not summary.failed and not summary.quarantined, summary.as_dict()
    return base / "warehouse"


@pytest.fixture(scope="session")
def demo_server(demo_wh):
    """One Streamlit app serving ``demo_wh`` for every browser test that looks at it (each opens its own pages)."""
    with serve_dashboard(demo_wh) as url:
        yield url


@pytest.fixture()
def app_env(monkeypatch):
    """Point the app at a warehouse (the env var the app honours) with fresh Streamlit caches."""
    import streamlit as st

    def use(root: Path):
        monkeypatch.setenv("STRIDELAB_WAREHOUSE", str(root))
        st.cache_data.clear()
        st.cache_resource.clear()
    return use


@pytest.fixture(scope="session")
def public_wh(tmp_path_factory) -> Path:
    """The small simulated demo study and the public study side by side: one recording of every public dataset
    in ../shared/data imported by ``import_public`` (skips when the data are absent), run by the real pipeline."""
    from stridelab.pipeline import runner
    from stridelab.pipeline.importers import import_public
    from stridelab.validation.simulate import simulate_to_dir
    from tests.conftest import SHARED_DATA
    if not SHARED_DATA.is_dir():
        pytest.skip(f"public data not found at {SHARED_DATA} (needs ../shared/data)")
    base = tmp_path_factory.mktemp("public")
    simulate_to_dir(base / "inbox", participants=1, hours=0.1, jobs=2)
    res = import_public(SHARED_DATA, base / "inbox" / "public", max_trials=1)
    assert not res.errors, res.errors
    summary = runner.run(base / "warehouse", base / "inbox", jobs=2, command="run")
    assert not summary.failed and not summary.quarantined, summary.as_dict()
    return base / "warehouse"
