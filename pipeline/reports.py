"""Participant reports as a tracked output of the run.

The ledger table ``reports`` records, per participant and output folder, the hash of the inputs a
report was built from (the participant's stage stamps and recordings, the report format and the
package version). Each run, under the run lock, writes every report that is missing from the
ledger, stale, or whose files are gone, so a run killed in the middle of writing reports is
completed by the next one. Files appear atomically (temporary name, fsync, rename: see
``reports/participant.py``); temporaries left by a killed run are removed first. The report builder
is passed in by the command line (the pipeline does not import the dashboard layer).
"""
from __future__ import annotations

import hashlib
import os
import pickle
from pathlib import Path
from typing import Callable

from stridelab.pipeline.stages import canonical_json
from stridelab.warehouse.catalog import Warehouse, first

#: bump when the report's content or layout changes: every report is then rewritten once
REPORT_FORMAT = 3                  # 2: clinician summary page, clinical measures, walking bouts (issue 18); 3: PDF laid out by ReportLab, tables whole
TMP_PREFIX = ".tmp-"

#: ``build(study, participant_id, out_dir) -> {"html": Path, "pdf": Path}``
ReportBuilder = Callable[[str, str, Path], dict]


def report_inputs(wh: Warehouse, study: str, participant: str, version: str) -> str:
    """Hash of everything a participant's report is built from."""
    stamps = wh.con.execute(
        "SELECT st.session_id, st.stage, st.stamp FROM stage_state st JOIN sessions s USING (session_id) "
        "WHERE s.study = ? AND s.participant_id = ? ORDER BY 1, 2", [study, participant]).fetchall()
    recs = wh.con.execute(
        "SELECT r.content_hash FROM recordings r JOIN sessions s USING (session_id) WHERE r.status = 'ingested' "
        "AND s.study = ? AND s.participant_id = ? ORDER BY 1", [study, participant]).fetchall()
    doc = {"format": REPORT_FORMAT, "version": version, "stages": [list(r) for r in stamps],
           "recordings": [r[0] for r in recs]}
    return hashlib.sha256(canonical_json(doc).encode()).hexdigest()


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_orphan_temporaries(out_dir: Path) -> int:
    """Delete ``.tmp-<pid>-*`` files of report writers that are no longer running (a killed run)."""
    removed = 0
    for p in Path(out_dir).glob(f"{TMP_PREFIX}*"):
        pid = p.name[len(TMP_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid() or not _pid_alive(int(pid)):
            p.unlink(missing_ok=True)
            removed += 1
    return removed


def _serial(fn: Callable, items: list, on_done: Callable) -> None:
    for it in items:
        try:
            r = fn(*it)
        except Exception as e:  # noqa: BLE001 - one report must not stop the others
            r = e
        on_done(it, r)


def _picklable(fn) -> bool:
    try:
        pickle.dumps(fn)
    except Exception:  # noqa: BLE001 - a closure or lambda: build in this process
        return False
    return True


def write_reports(wh: Warehouse, run_id: str, out_dir: Path, build: ReportBuilder, version: str,
                  on_progress: Callable[[str], None] = lambda m: None,
                  run_all: Callable | None = None) -> tuple[list[str], list[str]]:
    """Write every missing or stale report; returns (pdf paths written, failures as one line each).

    ``run_all(fn, items, on_done)`` (the local engine's: its worker processes) builds the reports in
    parallel when ``build`` can be pickled; otherwise, or without it, they are built one after the other
    in this process. Each written report is recorded in its own transaction, by this process, after its
    files are in place; a report that fails is not recorded (the next run tries again) and does not stop
    the others."""
    out_dir = Path(out_dir).resolve()
    written, failed = [], []
    if out_dir.is_dir():
        remove_orphan_temporaries(out_dir)
    with wh.transaction() as con:        # participants that no longer exist (a --replace moved them)
        con.execute("DELETE FROM reports WHERE (study, participant_id) NOT IN "
                    "(SELECT study, participant_id FROM participants)")
    who = wh.con.execute("SELECT DISTINCT s.study, s.participant_id FROM sessions s JOIN recordings r "
                         "USING (session_id) WHERE r.status = 'ingested' ORDER BY 1, 2").fetchall()
    todo, hashes = [], {}
    for study, pid in who:
        h = report_inputs(wh, study, pid, version)
        row = first(wh.con.execute("SELECT inputs_hash, html_path, pdf_path FROM reports WHERE study = ? AND "
                                   "participant_id = ? AND out_dir = ?", [study, pid, str(out_dir)]))
        if row is not None and row[0] == h and Path(row[1]).is_file() and Path(row[2]).is_file():
            continue
        todo.append((study, pid, out_dir))
        hashes[(study, pid)] = h

    def done(item, paths) -> None:
        study, pid, _ = item
        if isinstance(paths, BaseException):
            msg = str(paths).splitlines()[0] if str(paths) else type(paths).__name__
            failed.append(f"report {study}/{pid}: {msg}")
            on_progress(f"report {study}/{pid}: FAILED: {msg}")
            return
        with wh.transaction() as con:
            con.execute("INSERT OR REPLACE INTO reports VALUES (?, ?, ?, ?, ?, ?, ?, current_timestamp)",
                        [study, pid, str(out_dir), hashes[(study, pid)], str(paths["html"]), str(paths["pdf"]),
                         run_id])
        written.append(str(paths["pdf"]))
        on_progress(f"report {study}/{pid}: {paths['pdf']}")

    (run_all if run_all is not None and len(todo) > 1 and _picklable(build) else _serial)(build, todo, done)
    return written, failed
