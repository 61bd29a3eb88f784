"""Injected faults: disk full, read-only warehouse, a worker killed mid-task, Dask = local engine."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from stridelab.pipeline import runner
from tests.corpus import small_recording
from stridelab.pipeline.formats.mcap_write import write_recording
from tests.pipeline.test_runner import cli, make_inbox, snapshot_fingerprint
from stridelab.warehouse.catalog import first
from stridelab.warehouse.read import connect_snapshot


def _namespace_available() -> bool:
    if shutil.which("unshare") is None:
        return False
    cmd = ["unshare", "-m", "true"] if os.geteuid() == 0 else ["unshare", "-rm", "true"]
    return subprocess.run(cmd, capture_output=True).returncode == 0


needs_mount = pytest.mark.skipif(not _namespace_available(),
                                 reason="needs a private mount namespace (unshare -m) to mount a small tmpfs")


def _in_namespace(script: str) -> subprocess.CompletedProcess:
    pre = ["unshare", "-m", "--propagation", "private"] if os.geteuid() == 0 else ["unshare", "-rm"]
    return subprocess.run([*pre, "bash", "-c", script], capture_output=True, text=True, timeout=300)


#: the test-only fault hooks (tests/pipeline/fault_plugin/sitecustomize.py) on the path of the run and its workers
FAULT_PLUGIN = {"PYTHONPATH": os.pathsep.join(filter(None, [str(Path(__file__).parent / "fault_plugin"),
                                                           os.environ.get("PYTHONPATH")]))}


READ_COUNT = f"{sys.executable} -c \"import sys; from stridelab.warehouse.read import connect_snapshot; " \
             f"c = connect_snapshot(sys.argv[1]); print('RECORDINGS', c.execute('SELECT count(*) FROM recordings').fetchall()[0][0])\""


def _ingest_on_small_tmpfs(tmp_path: Path, break_fs: str, new_seconds: float) -> tuple[str, list[str]]:
    """Copy a one-recording warehouse onto a private tmpfs, break the filesystem with the shell lines
    ``break_fs``, ingest a new file there, then read the newest snapshot; returns (all output, error lines)."""
    f = write_recording(small_recording(seconds=5), tmp_path / "first.mcap")
    runner.run(tmp_path / "wh", None, files=[f], stages=False)
    new = write_recording(small_recording(seconds=new_seconds, session="S2", trial="new", seed=3), tmp_path / "new.mcap")
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    r = _in_namespace(textwrap.dedent(f"""
        set -e
        mount -t tmpfs -o size=48m tmpfs {mnt}
        cp -a {tmp_path / "wh"} {mnt}/wh
        {break_fs.replace("MNT", str(mnt))}
        set +e
        cd {os.getcwd()} && {sys.executable} -m stridelab ingest {new} --warehouse {mnt}/wh
        echo "EXIT $?"
        {READ_COUNT} {mnt}/wh
    """))
    return r.stdout + r.stderr, [line for line in r.stderr.splitlines() if line.startswith("error:")]


@needs_mount
@pytest.mark.slow
def test_disk_full_stops_the_run_with_a_clear_error_and_keeps_the_snapshot(tmp_path):
    # leave about 20 kB free: the new recording's series cannot be written
    out, err = _ingest_on_small_tmpfs(tmp_path, "avail=$(df --output=avail -B1 MNT | tail -1); "
                                                "fallocate -l $((avail - 20000)) MNT/filler", new_seconds=120)
    assert "EXIT 2" in out, out
    assert err and "No space left on device" in err[0] and "previous snapshot is still readable" in err[0], out
    assert "RECORDINGS 1" in out, out


@needs_mount
def test_read_only_warehouse_stops_with_a_clear_error_and_stays_readable(tmp_path):
    out, err = _ingest_on_small_tmpfs(tmp_path, "mount -o remount,ro MNT", new_seconds=5)
    assert "EXIT 2" in out, out
    assert err and "Read-only file system" in err[0], out
    assert "RECORDINGS 1" in out, out


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """(inbox of 2 sessions, fingerprint of a clean local run over it with 2 workers): the reference of the
    worker-kill and the Dask tests below, run once for both."""
    base = tmp_path_factory.mktemp("local_run")
    make_inbox(base / "inbox", n_sessions=2, seconds=10)
    clean = cli("run", "--inbox", base / "inbox", "--warehouse", base / "clean", "-j", "2")
    assert clean.returncode == 0, clean.stderr
    return base / "inbox", snapshot_fingerprint(base / "clean")


@pytest.mark.slow
def test_a_worker_killed_mid_task_is_retried_and_nothing_is_lost(tmp_path, local_run):
    inbox, expected = local_run
    marker = tmp_path / "killed-once"
    r = cli("run", "--inbox", inbox, "--warehouse", tmp_path / "wh", "-j", "2",
            env={"STRIDELAB_TEST_KILL_WORKER_ONCE": str(marker), **FAULT_PLUGIN})
    assert r.returncode == 0, r.stderr
    assert marker.exists(), "the fault was not injected"
    assert snapshot_fingerprint(tmp_path / "wh") == expected
    con = connect_snapshot(tmp_path / "wh")
    # every stage ran exactly once per session: nothing duplicated
    assert con.execute("SELECT stage, session_id, count(*) FROM stage_runs WHERE status = 'ok' GROUP BY ALL "
                       "HAVING count(*) > 1").fetchall() == []
    assert first(con.execute("SELECT count(*) FROM stage_runs WHERE stage = 'orientation' AND status = 'ok'"))[0] == 2


@pytest.mark.slow
def test_dask_engine_gives_the_same_warehouse_as_the_local_engine(tmp_path, local_run):
    inbox, local = local_run
    b = cli("run", "--inbox", inbox, "--warehouse", tmp_path / "dask", "-j", "2", "--engine", "dask")
    assert b.returncode == 0, b.stderr
    assert snapshot_fingerprint(tmp_path / "dask") == local


@pytest.mark.slow
def test_dask_worker_killed_mid_task_is_retried(tmp_path):
    make_inbox(tmp_path / "inbox", n_sessions=2, seconds=10)
    marker = tmp_path / "killed-once"
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "2", "--engine", "dask",
            env={"STRIDELAB_TEST_KILL_WORKER_ONCE": str(marker), **FAULT_PLUGIN})
    assert r.returncode == 0, r.stderr
    assert marker.exists()
    con = connect_snapshot(tmp_path / "wh")
    assert first(con.execute("SELECT count(*) FROM stage_runs WHERE stage = 'orientation' AND status = 'ok'"))[0] == 2
    assert first(con.execute("SELECT count(*) FROM orientation"))[0] == 16


@pytest.mark.slow
def test_coordinator_killed_mid_commit_then_rerun_equals_a_clean_run(tmp_path):
    make_inbox(tmp_path / "inbox", n_sessions=2, seconds=10)
    clean = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "clean", "-j", "1")
    assert clean.returncode == 0, clean.stderr
    marker = tmp_path / "killed"
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1",
            env={"STRIDELAB_TEST_KILL_COORDINATOR_IN_COMMIT": str(marker), **FAULT_PLUGIN})
    assert r.returncode == -9 and marker.exists()          # died between DELETE and INSERT of a stage commit
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1")
    assert r.returncode == 0, r.stderr
    assert snapshot_fingerprint(tmp_path / "wh") == snapshot_fingerprint(tmp_path / "clean")


def test_series_writer_flushes_in_the_background_and_a_failed_flush_fails_the_write(tmp_path, monkeypatch):
    """stridelab.warehouse.store.SeriesWriter pushes written rows to the disk every WRITEBACK_BYTES on a thread of
    its own; the file reads back whole, and an error of such a flush (disk full) fails the write and
    leaves no file behind."""
    import errno

    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from stridelab.warehouse import store
    monkeypatch.setattr(store, "WRITEBACK_BYTES", 1 << 16)
    tab = pa.table({"t_ns": np.arange(20_000, dtype=np.int64), "x": np.random.default_rng(0).normal(size=20_000)})
    flushes = []
    real = os.fdatasync
    monkeypatch.setattr(store.os, "fdatasync", lambda fd: flushes.append(fd) or real(fd))
    w = store.SeriesWriter(tmp_path, "series/ok.parquet", tab.schema)
    for _ in range(6):
        w.write(tab)
        # the writer never waits for a flush in progress (it skips starting another), so on a loaded machine
        # one slow fdatasync may cover all six writes; wait for each write and its flush to make the count exact
        w._pending[-1].result()
        if w._sync is not None:
            w._sync.result()
    w.commit()
    assert len(flushes) >= 5                       # 6 writes of 320 kB each pass 64 kiB
    assert pq.read_table(tmp_path / "series/ok.parquet").equals(pa.concat_tables([tab] * 6))

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(store.os, "fdatasync", full)
    w = store.SeriesWriter(tmp_path, "series/full.parquet", tab.schema)
    with pytest.raises(OSError, match="No space left"):
        for _ in range(6):
            w.write(tab)
        w.commit()
    w.abort()
    assert not (tmp_path / "series/full.parquet").exists()
    assert not [p for p in (tmp_path / "series").iterdir() if p.name.startswith(store.TMP_PREFIX)]


def test_series_of_one_recording_are_flushed_together_and_placed_only_when_all_flushes_succeeded(tmp_path,
                                                                                                 monkeypatch):
    """stridelab.warehouse.store.commit_all: every file is fsync'ed before any is moved into place, the flushes run side by
    side (up to FLUSH_THREADS at once), and one failed flush (disk full) places none of them."""
    import errno
    import threading

    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from stridelab.warehouse import store
    tab = pa.table({"t_ns": np.arange(1000, dtype=np.int64), "x": np.random.default_rng(1).normal(size=1000)})
    rels = [f"series/p/imu-{k}.parquet" for k in range(5)]

    def writers(tag):
        out = []
        for k in range(5):
            w = store.SeriesWriter(tmp_path, f"series/_staging/{tag}{k}.parquet", tab.schema)
            w.write(tab, last=True)
            out.append(w)
        return out

    real_fsync = os.fsync
    inside, peak, placed_early = [0], [0], []
    lock = threading.Lock()
    second = threading.Event()

    def slow_fsync(fd):
        with lock:
            inside[0] += 1
            peak[0] = max(peak[0], inside[0])
            placed_early.extend(r for r in rels if (tmp_path / r).exists())
            if inside[0] >= 2:
                second.set()
        second.wait(timeout=5)           # the first flush returns at once only if a second one starts meanwhile
        real_fsync(fd)
        with lock:
            inside[0] -= 1
    monkeypatch.setattr(store.os, "fsync", slow_fsync)
    assert store.commit_all(writers("a"), rels) == rels
    assert peak[0] >= 2 and placed_early == []
    for r in rels:
        assert pq.read_table(tmp_path / r).equals(tab)

    rels2 = [r.replace("imu", "mag") for r in rels]
    calls = [0]

    def full(fd):
        calls[0] += 1
        if calls[0] == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        real_fsync(fd)
    monkeypatch.setattr(store.os, "fsync", full)
    ws = writers("b")
    with pytest.raises(OSError, match="No space left"):
        store.commit_all(ws, rels2)
    for w in ws:
        w.abort()
    assert not any((tmp_path / r).exists() for r in rels2)
    assert not [p for p in (tmp_path / "series/_staging").iterdir() if p.name.startswith(store.TMP_PREFIX)]
