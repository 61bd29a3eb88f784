"""Killing only the coordinator (what the OOM killer does) takes its workers with it, local pool and Dask."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.pipeline.test_runner import STRIDELAB, make_inbox

#: how long the test waits for the workers to go after the kill (a bound on the wait, not a speed requirement:
#: they go within seconds; the time each took is printed)
WAIT_FOR_WORKERS_S = 60


def _children() -> dict[int, list[int]]:
    out: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            out.setdefault(ppid, []).append(int(d.name))
    return out


def _descendants(pid: int) -> list[int]:
    kids, todo, seen = _children(), [pid], []
    while todo:
        for c in kids.get(todo.pop(), []):
            seen.append(c)
            todo.append(c)
    return seen


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()[:90]
    except OSError:
        return "?"


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")            # a zombie has released everything; only its pid remains


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("engine", [pytest.param("local", marks=pytest.mark.slow),
                                    pytest.param("dask", marks=pytest.mark.slow)])
def test_killing_only_the_coordinator_leaves_no_worker_behind(tmp_path, engine):
    make_inbox(tmp_path / "inbox", n_sessions=2, seconds=10)
    coord = subprocess.Popen([*STRIDELAB, "run", "--inbox", str(tmp_path / "inbox"), "--warehouse",
                              str(tmp_path / "wh"), "-j", "2", "--engine", engine, "--no-reports"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 240
        snapshots = tmp_path / "wh" / "snapshots"
        while time.monotonic() < deadline and coord.poll() is None:
            # a published snapshot = a worker finished a task: the workers are up and busy (what the OOM
            # killer meets); a Dask worker killed within its first seconds of start-up, before its preload
            # ran, is left to Dask's own parent monitor (about 5-8 s here)
            if snapshots.is_dir() and list(snapshots.glob("catalog-*.duckdb")):
                workers = _descendants(coord.pid)
                break
            time.sleep(0.05)
        assert coord.poll() is None and len(workers) >= 2, "the run ended before its workers could be seen"
        names = {p: _cmdline(p) for p in workers}
        os.kill(coord.pid, signal.SIGKILL)
        coord.wait()
        t_kill = time.monotonic()
        survivors = workers
        gone_at: dict[int, float] = {}
        while survivors and time.monotonic() - t_kill < WAIT_FOR_WORKERS_S:
            for p in survivors:
                if not _alive(p):
                    gone_at[p] = time.monotonic() - t_kill
            survivors = [p for p in survivors if p not in gone_at]
            time.sleep(0.05)
        for p in workers:
            print(f"  pid {p} ({names.get(p, '?')}): gone after {gone_at.get(p, float('inf')):.2f} s")
        lived = time.monotonic() - t_kill
        print(f"{engine}: {len(workers)} descendants of the coordinator, last one gone {lived:.2f} s after the kill")
        assert not survivors, f"still alive {WAIT_FOR_WORKERS_S} s after the coordinator: {survivors}"
    finally:
        if coord.poll() is None:
            coord.kill()
            coord.wait()
        for p in workers:
            if not _alive(p):
                continue
            try:
                os.kill(p, signal.SIGKILL)      # only processes this test started
            except ProcessLookupError:
                pass
