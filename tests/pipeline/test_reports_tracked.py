"""Reports as a tracked output: a run writes every missing or stale report, a kill during the report
phase leaves no partial file, and the next run completes the set (issue 17 point 2)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from tests.pipeline.test_runner import STRIDELAB, cli, make_inbox
from stridelab.warehouse.read import connect_snapshot


STUDIES = ("a", "b", "c")


def _inbox(d: Path) -> None:
    for study in STUDIES:        # three participants: a/P000, b/P000, c/P000
        make_inbox(d, n_sessions=1, seconds=6, study=study)


def _expected() -> set[str]:
    return {f"{s}_P000.{ext}" for s in STUDIES for ext in ("html", "pdf")}


def _complete(p: Path) -> bool:
    data = p.read_bytes()
    if p.suffix == ".pdf":
        return data.startswith(b"%PDF") and data.rstrip().endswith(b"%%EOF")
    return data.rstrip().endswith(b"</html>")


def _run(tmp_path, *extra):
    return cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1",
               "--reports", tmp_path / "reports", "--json", *extra)


def _kill_when(tmp_path, seen) -> None:
    """Start a run and SIGKILL it as soon as ``seen(reports_dir)`` is true (polled every 10 ms)."""
    p = subprocess.Popen([*STRIDELAB, "run", "--inbox", str(tmp_path / "inbox"), "--warehouse", str(tmp_path / "wh"),
                          "-j", "1", "--reports", str(tmp_path / "reports")],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 600
        while p.poll() is None and time.monotonic() < deadline:
            if (tmp_path / "reports").is_dir() and seen(tmp_path / "reports"):
                os.kill(p.pid, signal.SIGKILL)
                break
            time.sleep(0.01)
        p.wait(timeout=60)
        assert p.returncode == -9, "the run ended before the kill point"
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()


@pytest.mark.parametrize("kill_point", [
    pytest.param("while-writing", marks=pytest.mark.slow),   # a temporary report file exists: killed mid-file
    pytest.param("after-first", marks=pytest.mark.slow),   # the first report is complete
])
def test_a_run_killed_while_writing_reports_is_completed_by_the_next_run(tmp_path, kill_point):
    _inbox(tmp_path / "inbox")
    if kill_point == "while-writing":
        _kill_when(tmp_path, lambda d: any(x.name.startswith(".tmp-") for x in d.iterdir()))
    else:
        _kill_when(tmp_path, lambda d: any(x.suffix == ".pdf" and not x.name.startswith(".") for x in d.iterdir()))
    after_kill = sorted(x.name for x in (tmp_path / "reports").iterdir() if not x.name.startswith("."))
    print(f"{kill_point}: after the kill {len(after_kill)} of {len(_expected())} report files: {after_kill}")
    assert set(after_kill) < _expected()                   # some missing ...
    for name in after_kill:                                # ... and none partial under its final name
        assert _complete(tmp_path / "reports" / name), name

    r = _run(tmp_path)
    assert r.returncode == 0, r.stderr
    assert {x.name for x in (tmp_path / "reports").iterdir()} == _expected()   # no temporaries left
    assert all(_complete(x) for x in (tmp_path / "reports").iterdir())
    assert len(json.loads(r.stdout)["reports"]) >= len(STUDIES) - len(after_kill) // 2

    r = _run(tmp_path)                                     # nothing missing, nothing stale: nothing written
    assert r.returncode == 0 and json.loads(r.stdout)["reports"] == [], r.stdout


@pytest.mark.slow
def test_missing_or_stale_reports_are_rewritten_and_fresh_ones_are_not(tmp_path):
    _inbox(tmp_path / "inbox")
    r = _run(tmp_path)
    assert r.returncode == 0, r.stderr
    assert len(json.loads(r.stdout)["reports"]) == 3
    mtimes = {x.name: x.stat().st_mtime_ns for x in (tmp_path / "reports").iterdir()}
    (tmp_path / "reports" / "b_P000.pdf").unlink()                    # someone deleted a report
    make_inbox(tmp_path / "inbox", n_sessions=1, seconds=6, study="d")    # a new participant d/P000
    r = _run(tmp_path)
    assert r.returncode == 0, r.stderr
    written = sorted(Path(p).name for p in json.loads(r.stdout)["reports"])
    assert written == ["b_P000.pdf", "d_P000.pdf"]
    for name in ("a_P000.pdf", "a_P000.html", "c_P000.pdf"):          # fresh reports were left alone
        assert (tmp_path / "reports" / name).stat().st_mtime_ns == mtimes[name]
    con = connect_snapshot(tmp_path / "wh")
    assert con.execute("SELECT count(*) FROM reports").fetchall()[0][0] == 4
