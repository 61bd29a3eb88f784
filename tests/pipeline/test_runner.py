"""The nightly runner end to end through the real CLI: staleness, kill -9, snapshots, lock, isolation."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from stridelab.pipeline.formats.mcap_write import write_recording
from tests.corpus import small_recording
from stridelab.warehouse.catalog import Warehouse, first, fingerprint
from stridelab.warehouse.lock import RunLock
from stridelab.warehouse.read import connect_snapshot, latest_snapshot

STRIDELAB = [sys.executable, "-m", "stridelab"]


def cli(*args, env=None, **kw):
    return subprocess.run([*STRIDELAB, *map(str, args)], capture_output=True, text=True,
                          env={**os.environ, **(env or {})}, timeout=600, **kw)


def _study_seed(study: str) -> int:
    """Seed offset of a study's recordings."""
    import zlib
    return 1000 * (zlib.crc32(study.encode()) % 100000)


def make_inbox(d: Path, n_sessions: int = 3, seconds: float = 30.0, study: str = "testing") -> list[Path]:
    d.mkdir(parents=True, exist_ok=True)
    files = []
    for i in range(n_sessions):
        for j, trial in enumerate(("walk-1", "walk-2")):
            # distinct samples per trial and study (equal samples would be one recording, a re-export)
            rec = small_recording(seconds=seconds, seed=10 * i + j + _study_seed(study), session=f"{study}-S{i:02d}",
                                  participant=f"P{i % 2:03d}", trial=trial, study=study,
                                  placements=("foot_left", "foot_right", "shank_left", "pelvis"))
            files.append(write_recording(rec, d / f"{study}_S{i:02d}_{trial}.mcap"))
    return files


def snapshot_fingerprint(root: Path) -> dict:
    con = connect_snapshot(root)
    try:
        return fingerprint(con, root)
    finally:
        con.close()


@pytest.mark.slow
def test_run_computes_orientation_for_every_imu_then_is_fresh(tmp_path):
    make_inbox(tmp_path / "inbox", n_sessions=2, seconds=10)
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "--jobs", "1", "--json",
            "--reports", tmp_path / "reports")
    assert r.returncode == 0, r.stderr
    reports = json.loads(r.stdout)["reports"]                 # participants with new results get a report
    assert sorted(Path(p).name for p in reports) == ["testing_P000.pdf", "testing_P001.pdf"]
    assert all(Path(p).stat().st_size > 10_000 for p in reports)
    con = connect_snapshot(tmp_path / "wh")
    n_imu = first(con.execute("SELECT count(*) FROM sensors WHERE kind = 'imu'"))[0]
    assert n_imu == 16
    assert first(con.execute("SELECT count(*) FROM orientation"))[0] == n_imu
    assert first(con.execute("SELECT count(*) FROM stage_runs WHERE stage = 'orientation' AND status = 'ok'"))[0] == 2
    n_stages = first(con.execute("SELECT count(DISTINCT stage) FROM stage_runs"))[0]
    # the ledger holds each run's CPU seconds beside its wall seconds (migration 011)
    least_cpu, no_cpu = first(con.execute("SELECT min(cpu_s), count(*) FILTER (WHERE cpu_s IS NULL) FROM stage_runs "
                                          "WHERE status = 'ok'"))
    assert least_cpu > 0 and no_cpu == 0
    con.close()
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "--jobs", "1", "--json",
            "--reports", tmp_path / "reports")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["reports"] == []
    out = json.loads(r.stdout)
    assert (out["stage_runs"], out["fresh"], out["ingested"]) == (0, 2 * n_stages, 0)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """(inbox, fingerprint of an uninterrupted run over it): the reference of both kill points below, made once
    (the same inbox run twice to the same fingerprint proved nothing more)."""
    base = tmp_path_factory.mktemp("uninterrupted")
    make_inbox(base / "inbox", n_sessions=3, seconds=60)
    clean = cli("run", "--inbox", base / "inbox", "--warehouse", base / "clean", "--jobs", "2")
    assert clean.returncode == 0, clean.stderr
    return base / "inbox", snapshot_fingerprint(base / "clean")


@pytest.mark.slow
@pytest.mark.parametrize("kill_at_snapshot", [2, 7])     # during ingest (6 files), during the stages (3 sessions)
def test_kill_9_then_rerun_equals_an_uninterrupted_run(tmp_path, kill_at_snapshot, uninterrupted):
    inbox, expected = uninterrupted
    wh = tmp_path / "killed"
    # a snapshot after every commit (not at most every PUBLISH_INTERVAL_S), so that the snapshot count marks
    # the point of the run to kill it at
    p = subprocess.Popen([*STRIDELAB, "run", "--inbox", str(inbox), "--warehouse", str(wh), "--jobs", "2"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                         env={**os.environ, "STRIDELAB_PUBLISH_INTERVAL_S": "0"})
    deadline = time.time() + 300
    while time.time() < deadline:
        snap = latest_snapshot(wh)
        if snap is not None and int(snap.stem.split("-")[1]) >= kill_at_snapshot:
            break
        if p.poll() is not None:
            break
        time.sleep(0.005)
    os.killpg(p.pid, signal.SIGKILL)                  # the coordinator and its workers
    p.wait()
    assert p.returncode == -signal.SIGKILL
    con = connect_snapshot(wh)
    status = first(con.execute("SELECT status FROM pipeline_runs"))[0]
    done = first(con.execute("SELECT count(*) FROM stage_runs WHERE stage = 'orientation' AND status = 'ok'"))[0]
    con.close()
    assert status == "running" and done < 3, "the run finished before it was killed: the test proved nothing"

    r = cli("run", "--inbox", inbox, "--warehouse", wh, "--jobs", "2")
    assert r.returncode == 0, r.stderr
    assert snapshot_fingerprint(wh) == expected
    con = connect_snapshot(wh)
    statuses = [s for (s,) in con.execute("SELECT status FROM pipeline_runs ORDER BY started_at").fetchall()]
    assert statuses == ["interrupted", "ok"]
    assert not list(wh.rglob(".tmp-*"))


@pytest.mark.slow
def test_a_reader_holding_a_snapshot_neither_blocks_nor_is_blocked(tmp_path):
    make_inbox(tmp_path / "inbox", n_sessions=1, seconds=10)
    assert cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1").returncode == 0
    reader = connect_snapshot(tmp_path / "wh")
    before = first(reader.execute("SELECT count(*) FROM recordings"))[0]
    make_inbox(tmp_path / "inbox2", n_sessions=2, seconds=10, study="more")
    # a run blocked by the reader would hang: cli()'s subprocess timeout fails the test then (no wall-time assertion)
    r = cli("run", "--inbox", tmp_path / "inbox2", "--warehouse", tmp_path / "wh", "-j", "1")
    assert r.returncode == 0, r.stderr
    # the old snapshot still answers, unchanged; a new reader sees the new data
    assert first(reader.execute("SELECT count(*) FROM recordings"))[0] == before
    reader.close()
    fresh = connect_snapshot(tmp_path / "wh")
    assert first(fresh.execute("SELECT count(*) FROM recordings"))[0] == before + 4


@pytest.mark.slow
def test_second_concurrent_run_refuses_with_a_clear_message(tmp_path):
    (tmp_path / "wh").mkdir()
    with RunLock(tmp_path / "wh", "stridelab run (test holder)"):
        r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh")
    assert r.returncode == 2
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith("error: another stridelab process") and "test holder" in line


@pytest.mark.slow
def test_a_failing_session_is_recorded_and_does_not_block_the_others(tmp_path):
    studies = tmp_path / "studies" / "broken"
    studies.mkdir(parents=True)
    (studies / "study.toml").write_text('[stages.orientation]\nestimator = "no-such-filter"\n')
    make_inbox(tmp_path / "inbox", n_sessions=1, seconds=10, study="broken")
    make_inbox(tmp_path / "inbox", n_sessions=1, seconds=10, study="fine")
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1",
            env={"STRIDELAB_STUDIES": str(tmp_path / "studies")})
    assert r.returncode == 1
    assert "unknown orientation estimator 'no-such-filter'" in r.stderr
    con = connect_snapshot(tmp_path / "wh")
    rows = con.execute("SELECT s.study, r.status FROM stage_runs r JOIN sessions s USING (session_id) "
                       "WHERE r.stage = 'orientation'").fetchall()
    assert sorted(rows) == [("broken", "failed"), ("fine", "ok")]
    assert first(con.execute("SELECT count(*) FROM stage_runs WHERE status = 'failed' AND cpu_s IS NOT NULL"))[0] == 0
    assert first(con.execute("SELECT count(*) FROM orientation"))[0] == 8


@pytest.mark.slow
def test_an_older_warehouse_is_upgraded_in_place(tmp_path):
    f = write_recording(small_recording(seconds=5), tmp_path / "a.mcap")
    with Warehouse.open(tmp_path / "wh", migrate_upto=1) as wh:
        assert first(wh.con.execute("SELECT max(version) FROM schema_migrations"))[0] == 1
        assert not wh.con.execute("SELECT * FROM information_schema.tables WHERE table_name = 'orientation'").fetchall()
    from stridelab.pipeline import ingest
    with Warehouse.open(tmp_path / "wh", migrate_upto=1) as wh:
        ingest.commit(wh, ingest.prepare(f, wh.root))
    r = cli("run", "--inbox", tmp_path / "none", "--warehouse", tmp_path / "wh", "-j", "1")
    assert r.returncode == 0, r.stderr
    con = connect_snapshot(tmp_path / "wh")
    assert [v for (v,) in con.execute("SELECT version FROM schema_migrations ORDER BY 1").fetchall()][:2] == [1, 2]
    assert first(con.execute("SELECT count(*) FROM orientation"))[0] == 2


def test_snapshots_are_published_at_most_once_per_interval_and_at_each_phase_end(monkeypatch):
    """Commits publish a snapshot only when PUBLISH_INTERVAL_S has passed since the last one; a phase end
    (``flush``) publishes what is still unpublished, and nothing when all is published; 0 (or the env
    variable) publishes after every commit."""
    from stridelab.pipeline import runner

    class FakeWarehouse:
        published = 0

        def publish_snapshot(self):
            self.published += 1

    clock = [100.0]
    monkeypatch.setattr(runner.time, "monotonic", lambda: clock[0])
    monkeypatch.delenv("STRIDELAB_PUBLISH_INTERVAL_S", raising=False)
    wh = FakeWarehouse()
    pub = runner._Publisher(wh)
    assert pub.interval == runner.PUBLISH_INTERVAL_S > 0
    pub.due()                                   # the first commit of a run is visible at once
    assert wh.published == 1
    for _ in range(5):                          # a burst of commits within the interval
        clock[0] += runner.PUBLISH_INTERVAL_S / 10
        pub.due()
    assert wh.published == 1
    pub.flush()                                 # end of a phase: the burst becomes visible
    assert wh.published == 2
    pub.flush()                                 # nothing new: no copy of the catalog
    assert wh.published == 2
    clock[0] += runner.PUBLISH_INTERVAL_S
    pub.due()
    assert wh.published == 3

    monkeypatch.setenv("STRIDELAB_PUBLISH_INTERVAL_S", "0")
    wh0 = FakeWarehouse()
    pub0 = runner._Publisher(wh0)
    for _ in range(4):
        pub0.due()
    assert wh0.published == 4

    monkeypatch.setenv("STRIDELAB_PUBLISH_INTERVAL_S", "soon")
    with pytest.raises(ValueError, match="STRIDELAB_PUBLISH_INTERVAL_S='soon' is not a number of seconds"):
        runner._Publisher(wh0)


def test_a_stage_level_hands_the_largest_sessions_tasks_out_first():
    """Tasks of the session with the most IMU samples first, whatever their stage; equal sizes keep their order."""
    from stridelab.pipeline.runner import _largest_first
    batch = [("orientation", "P1-lab"), ("activity", "P1-free"), ("trunk_gait", "P1-lab"), ("trunk_gait", "P1-free"),
             ("gait", "P2-lab")]
    samples = {"P1-lab": 2_000, "P1-free": 17_000_000, "P2-lab": 3_000}
    got = _largest_first(batch, lambda it: samples.get(it[1], 0))
    assert got == [("activity", "P1-free"), ("trunk_gait", "P1-free"), ("gait", "P2-lab"), ("orientation", "P1-lab"),
                   ("trunk_gait", "P1-lab")]
