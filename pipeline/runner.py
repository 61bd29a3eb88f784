"""The nightly runner: ingest what is new, recompute what is stale, keep a ledger, never lose data.

One process writes (the coordinator, holding the run lock); ``--jobs N`` worker processes decode
files and compute stage outputs, writing immutable Parquet files and handing catalog rows back.
Every committed step (a file, or one stage of one session) is one transaction followed by a
published snapshot, so ``kill -9`` at any moment leaves a consistent warehouse and a rerun
finishes the work with exactly the result of an uninterrupted run (outputs are deterministic and
their file names derive from their inputs).
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import socket
import time
import traceback
import uuid
from dataclasses import dataclass, field
from datetime import datetime, timezone
from importlib.metadata import version as pkg_version
from pathlib import Path
from typing import Callable, Iterable

from stridelab.pipeline.privacy import stored_name, stored_path
from stridelab.pipeline import ingest as ingest_mod
from stridelab.pipeline.formats.rosbag2 import is_bag
from stridelab.pipeline.engines import make_engine
from stridelab.pipeline.reports import ReportBuilder, write_reports
from stridelab.pipeline.config import requested, stage_params
from stridelab.pipeline.stages import SessionInput, Stage, StageOutput, canonical_json, params_hash, registry, stamp
from stridelab.warehouse.catalog import first, Warehouse
from stridelab.warehouse.lock import RunLock


STORAGE_ERRNOS = {errno.ENOSPC, errno.EROFS, errno.EDQUOT, errno.EACCES, errno.EPERM}


class StorageError(RuntimeError):
    """The warehouse cannot be written (disk full, read-only, permissions): the run stops."""


def _storage_problem(e: BaseException) -> bool:
    if isinstance(e, OSError) and e.errno in STORAGE_ERRNOS:
        return True
    text = str(e)
    return any(m in text for m in ("No space left on device", "Read-only file system", "Disk quota exceeded"))


@dataclass
class RunSummary:
    run_id: str
    ingested: list[str] = field(default_factory=list)
    duplicates: list[str] = field(default_factory=list)
    reexports: list[str] = field(default_factory=list)       # same samples as an ingested recording: not ingested
    quarantined: list[str] = field(default_factory=list)
    stage_runs: int = 0
    skipped_fresh: int = 0
    failed: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)          # inbox entries that cannot be recordings, with why
    skipped_topics: list[str] = field(default_factory=list)   # ``file: topic: reason`` of every topic not ingested
    messages: list[str] = field(default_factory=list)
    reports: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def as_dict(self) -> dict:
        return {"run_id": self.run_id, "ingested": len(self.ingested), "duplicates": len(self.duplicates),
                "reexports": self.reexports, "quarantined": self.quarantined, "stage_runs": self.stage_runs, "fresh": self.skipped_fresh,
                "failed": self.failed, "skipped": self.skipped, "skipped_topics": self.skipped_topics,
                "reports": self.reports,
                "seconds": round(self.seconds, 2)}


def _now() -> datetime:
    return datetime.now(timezone.utc).replace(tzinfo=None)


def _version() -> str:
    try:
        return pkg_version("stridelab")
    except Exception:  # noqa: BLE001
        return "dev"


# ---- worker-side functions (top level so they pickle) -------------------------------------

#: least seconds between two snapshots published while a run commits (env ``STRIDELAB_PUBLISH_INTERVAL_S``;
#: 0 publishes after every commit). Each phase and the run end with one, so readers see a run's progress at
#: most this late. Publishing copies the whole catalog (18 MB for 20 participants, growing with the study): once
#: per task, a 20-participant night made 201 copies and the coordinator spent ~10 s of its time in them.
PUBLISH_INTERVAL_S = 2.0


class _Publisher:
    """Publishes the catalog after commits, at most once per ``PUBLISH_INTERVAL_S`` (:meth:`due`), and on
    :meth:`flush` when something was committed since the last snapshot."""

    def __init__(self, wh: Warehouse, interval_s: float | None = None):
        self.wh = wh
        env = os.environ.get("STRIDELAB_PUBLISH_INTERVAL_S", "").strip()
        if interval_s is None and env:
            try:
                interval_s = float(env)
            except ValueError:
                raise ValueError(f"STRIDELAB_PUBLISH_INTERVAL_S={env!r} is not a number of seconds; "
                                 "set it to e.g. 2 (or 0: a snapshot after every commit)") from None
        self.interval = PUBLISH_INTERVAL_S if interval_s is None else max(0.0, float(interval_s))
        self.last = float("-inf")
        self.dirty = False

    def due(self) -> None:
        self.dirty = True
        if time.monotonic() - self.last >= self.interval:
            self.flush()

    def flush(self) -> None:
        if self.dirty:
            self.wh.publish_snapshot()
            self.last = time.monotonic()
            self.dirty = False


def _stage_task(stage_name: str, inp: SessionInput, params: dict) -> tuple[StageOutput, float, float]:
    """Run one stage on one session in a worker: (output, wall seconds, CPU seconds of this process)."""
    stage = {s.name: s for s in registry()}[stage_name]
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        out = stage.compute(inp, params)
    except Exception as e:
        if _storage_problem(e):
            raise StorageError(f"cannot write the warehouse: {e}") from None
        tb = traceback.extract_tb(e.__traceback__)
        where = f" ({Path(tb[-1].filename).name}:{tb[-1].lineno})" if tb else ""
        raise RuntimeError(f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}{where}") from None
    return out, time.perf_counter() - t0, time.process_time() - c0


# ---- coordinator ---------------------------------------------------------------------------

def _no_phase(name: str, total: int) -> None:
    return None


def ingest_files(wh: Warehouse, files: Iterable[Path], ex, summary: RunSummary,
                 on_progress: Callable[[str], None] = lambda m: None,
                 on_phase: Callable[[str, int], None] = _no_phase, options: dict | None = None,
                 replace: Iterable[Path] = (), publisher: _Publisher | None = None) -> None:
    """Ingest ``files``; those also in ``replace`` supersede the recordings they correct (``--replace``)."""
    publisher = publisher or _Publisher(wh)
    replacing = {str(Path(f).resolve()) for f in replace}
    if wh.has_column("recordings", "sample_hash") and ingest_mod.has_legacy_sample_hashes(wh.con):
        options = dict(options or {}, legacy_sample_hash=True)     # re-exports of recordings hashed before XXH3
    todo, seen = [], set()
    for f in files:
        f = Path(f)
        if str(f.resolve()) in seen:        # named with --replace and found in the inbox too
            continue
        seen.add(str(f.resolve()))
        if not (f.is_file() or is_bag(f)):
            summary.quarantined.append(f"{f}: not a recording file or rosbag2 bag directory (metadata.yaml)")
            continue
        if str(f.resolve()) in replacing:
            todo.append((str(f), str(wh.root), options) if options else (str(f), str(wh.root)))
            continue
        h = ingest_mod.known_hash(wh, f)
        if h is not None and first(wh.con.execute("SELECT 1 FROM recordings WHERE content_hash = ?", [h])) and (
                not wh.has_column("recordings", "settings_hash")
                or ingest_mod.stored_settings_hash(wh.con, h) == ingest_mod.settings_hash(options)):
            # the same file with the same ingest settings (other settings: ingested again, superseding)
            summary.duplicates.append(f.name)
            continue
        todo.append((str(f), str(wh.root), options) if options else (str(f), str(wh.root)))
    on_phase("ingest", len(todo))

    def done(item, res):
        if isinstance(res, Exception) and (isinstance(res, StorageError) or _storage_problem(res)):
            raise StorageError(f"cannot write the warehouse while ingesting {Path(item[0]).name}: {res}")
        if isinstance(res, Exception):
            res = ingest_mod.Prepared(source_path=stored_path(item[0]), file_name=stored_name(item[0]), size_bytes=0,
                                      mtime_ns=0, content_hash=ingest_mod.sha256(Path(item[0])), status="quarantined",
                                      reason=ingest_mod.redacted(f"internal error while reading: {res}", Path(item[0]), ()),
                                      display_name=Path(item[0]).name)
        r = ingest_mod.commit(wh, res, replace=str(Path(item[0]).resolve()) in replacing, run_id=summary.run_id)
        if r.status == "ingested":
            summary.skipped_topics += [f"{res.display_name or res.file_name}: {d['topic']}: {d['reason']}"
                                       for d in res.skipped_topics]
        {"ingested": summary.ingested, "duplicate": summary.duplicates, "reexport": summary.reexports,
         "quarantined": summary.quarantined}[r.status].append(
            r.message if r.status in ("quarantined", "reexport") else (res.display_name or res.file_name))
        summary.messages.append(r.message)
        publisher.due()
        on_progress(r.message)

    ex.run_all(ingest_mod.prepare, todo, done)
    publisher.flush()


def inbox_recordings(inbox: Path) -> list[Path]:
    """Recordings of an inbox: ``*.mcap`` files and rosbag2 bag directories (a bag is one recording,
    its files are not listed on their own); ``.db3`` files outside a bag and ROS 1 ``.bag`` files are listed so
    that they are reported (refused with the fix), never skipped silently. Entries that cannot be recordings are
    listed by :func:`inbox_skipped`."""
    return inbox_entries(inbox)[0]


def inbox_skipped(inbox: Path) -> list[str]:
    """``path: reason`` of every inbox entry that is skipped: dangling or looping symbolic links, links to
    directories (not followed), FIFOs, sockets and devices, a directory with a recording's name that is no bag."""
    return [f"{p}: {why}" for p, why in inbox_entries(inbox)[1]]


RECORDING_SUFFIXES = (".mcap", ".db3", ".bag")


def inbox_entries(inbox: Path) -> tuple[list[Path], list[tuple[Path, str]]]:
    """(recordings, skipped entries with the reason) of an inbox, walked without following directory links
    (a link loop can never hang the walk)."""
    import stat as st_
    recs: list[Path] = []
    skipped: list[tuple[Path, str]] = []
    for top, dirs, files in os.walk(inbox, followlinks=False):
        top_p = Path(top)
        if top_p != Path(inbox) and (top_p / "metadata.yaml").is_file():
            recs.append(top_p)                       # a bag: one recording, not descended into
            dirs[:] = []
            continue
        keep = []
        for d in sorted(dirs):
            p = top_p / d
            if d.startswith("."):
                continue
            if p.is_symlink():
                skipped.append((p, "a symbolic link to a directory: not followed (copy or move the folder into "
                                   "the inbox)"))
                continue
            if Path(d).suffix in RECORDING_SUFFIXES and not (p / "metadata.yaml").is_file():
                skipped.append((p, "a directory with a recording's name but no metadata.yaml: not a recording"))
            keep.append(d)
        dirs[:] = keep
        for name in sorted(files):
            if name.startswith("."):
                continue
            p = top_p / name
            try:
                mode = os.stat(p).st_mode                 # follows a link to its target
            except OSError as e:
                if p.is_symlink():
                    skipped.append((p, "a symbolic link loop" if e.errno == errno.ELOOP
                                    else "a dangling symbolic link (its target is missing)"))
                elif Path(name).suffix in RECORDING_SUFFIXES:
                    skipped.append((p, f"cannot be read ({e.strerror})"))
                continue
            if st_.S_ISDIR(mode):
                skipped.append((p, "a symbolic link to a directory: not followed (copy or move the folder into "
                                   "the inbox)"))
            elif not st_.S_ISREG(mode):
                kind = ("a FIFO" if st_.S_ISFIFO(mode) else "a socket" if st_.S_ISSOCK(mode)
                        else "a device" if (st_.S_ISCHR(mode) or st_.S_ISBLK(mode)) else "not a regular file")
                skipped.append((p, f"{kind}, not a regular file"))
            elif Path(name).suffix in RECORDING_SUFFIXES:
                recs.append(p)
    return sorted(recs), sorted(skipped)


def _session_inputs(wh: Warehouse, session_id: str, stage: Stage) -> SessionInput:
    con = wh.con
    cols = [d[0] for d in con.execute("SELECT * FROM sessions LIMIT 0").description]
    session = dict(zip(cols, first(con.execute("SELECT * FROM sessions WHERE session_id = ?", [session_id]))))
    recs = []
    for h, trial, start, end, meta in con.execute(
            "SELECT content_hash, trial, start_ns, end_ns, metadata FROM recordings "
            "WHERE session_id = ? AND status = 'ingested' ORDER BY start_ns, content_hash", [session_id]).fetchall():
        sensors: dict = {}
        for pl, kind, path, rate, n in con.execute(
                "SELECT placement, kind, series_path, sampling_rate_hz, n_samples FROM sensors WHERE content_hash = ? "
                "ORDER BY topic", [h]).fetchall():
            sensors.setdefault(pl, {})[kind if kind != "range" else f"range:{path}"] = {
                "series_path": path, "sampling_rate_hz": rate, "n_samples": n}
        recs.append({"content_hash": h, "trial": trial, "start_ns": start, "end_ns": end, "sensors": sensors,
                     "metadata": json.loads(meta) if meta else {}})
    upstream = {}
    stages = {s.name: s for s in registry()}
    for t in stage.reads:                       # catalog tables the ingest writes that the stage reads
        q = con.execute(f'SELECT * FROM "{t}" WHERE session_id = ?', [session_id])
        upstream[t] = [dict(zip([d[0] for d in q.description], r)) for r in q.fetchall()]
    for need in stage.needs:
        for t in stages[need].tables:
            q = con.execute(f'SELECT * FROM "{t}" WHERE session_id = ?', [session_id])
            names = [d[0] for d in q.description]
            upstream[t] = [dict(zip(names, r)) for r in q.fetchall()]
    q = con.execute("SELECT t_ns, end_ns, type, side, placement, label, payload FROM reference_events "
                    "WHERE session_id = ? "
                    "ORDER BY t_ns", [session_id])
    names = [d[0] for d in q.description]
    events = [dict(zip(names, r)) for r in q.fetchall()]
    return SessionInput(root=str(wh.root), session=session, recordings=recs, upstream=upstream, events=events)


def _input_hash(wh: Warehouse, session_id: str, stage: Stage) -> str:
    hashes = [r[0] for r in wh.con.execute(
        "SELECT content_hash FROM recordings WHERE session_id = ? AND status = 'ingested' ORDER BY 1",
        [session_id]).fetchall()]
    ups = [r for r in wh.con.execute(
        "SELECT stage, stamp FROM stage_state WHERE session_id = ? ORDER BY stage", [session_id]).fetchall()
        if r[0] in stage.needs]
    return hashlib.sha256(canonical_json({"recordings": hashes, "upstream": ups}).encode()).hexdigest()


def why_wanted(stage: Stage, kind: str, study: str, stages: list[Stage]) -> str | None:
    """Why ``stage`` runs on a ``kind`` session of ``study`` (None: nothing consumes its output there).

    A stage runs where a later stage that runs there needs it, where the study's manifest asks for it,
    and on its other session kinds because its output is read there (pages, reports); on an
    ``opt_in_kinds`` kind only the first two count."""
    if kind not in stage.session_kinds:
        return None
    users = [s.name for s in stages if stage.name in s.needs and why_wanted(s, kind, study, stages) is not None]
    if users:
        return f"needed by {', '.join(users)}"
    if requested(study, stage.name, kind):
        return f"requested by study {study} ([compute.{stage.name}] {kind} = true)"
    if kind in stage.opt_in_kinds:
        return None
    return f"output of {kind} sessions"


def _why_stale(wh: Warehouse, session_id: str, stage: Stage, params: dict, input_hash: str, has_state: bool) -> str:
    """What changed since the stage last ran on the session (the ledger's previous entry)."""
    last = first(wh.con.execute(
        "SELECT status, stage_version, params_hash, input_hash FROM stage_runs WHERE session_id = ? AND stage = ? "
        "ORDER BY started_at DESC LIMIT 1", [session_id, stage.name]))
    if last is None:
        return "first run"
    status, version, ph, ih = last
    if status not in ("ok", "skipped"):
        return "retry after a failure"
    if not has_state:
        return "outputs missing"
    if version != stage.version:
        return f"stage version {version} -> {stage.version}"
    if ph != params_hash(params):
        return "parameters changed"
    if ih is not None and ih != input_hash:
        return "inputs changed"
    return "stamp changed"


def run_stages(wh: Warehouse, run_id: str, ex, summary: RunSummary,
               on_progress: Callable[[str], None] = lambda m: None, only_sessions: list[str] | None = None,
               on_phase: Callable[[str, int], None] = _no_phase, publisher: _Publisher | None = None) -> None:
    publisher = publisher or _Publisher(wh)
    sessions = wh.con.execute("SELECT session_id, study, kind FROM sessions ORDER BY session_id").fetchall()
    if only_sessions is not None:
        sessions = [s for s in sessions if s[0] in only_sessions]
    failed_sessions: dict[str, str] = {}
    stages = registry()
    by_name = {s.name: s for s in stages}
    # a task's size: its session's IMU samples (a free-living day's activity and trunk-gait tasks take seconds, a
    # lab session's stages a fraction of one)
    samples = dict(wh.con.execute(
        "SELECT r.session_id, coalesce(sum(s.n_samples), 0) FROM sensors s JOIN recordings r USING (content_hash) "
        "WHERE r.status = 'ingested' AND s.kind = 'imu' GROUP BY 1").fetchall())
    for level in stage_levels(stages):
        batch, dispatch = [], {}
        for stage in level:
            tasks, why = _plan_stage(wh, stage, stages, sessions, failed_sessions, summary)
            if not tasks:
                continue

            def done(item, res, stage=stage, why=why):
                _commit_stage_result(wh, run_id, stage, why, item, res, failed_sessions, summary, on_progress)
                publisher.due()

            batch += tasks
            dispatch[stage.name] = done
        # one pool pass per level: the stages of a level need nothing of each other, so a session's long
        # activity day and other sessions' lab stages share the workers without a barrier between stages.
        # A task's inputs are read from the catalog as the pool takes it (the engine drains the generator
        # before it commits any result of the level): the workers start on the first tasks meanwhile
        on_phase(" + ".join(dispatch), len(batch))
        items = ((name, _session_inputs(wh, sid, by_name[name]), params, st)
                 for name, sid, params, st in _largest_first(batch, lambda it: samples.get(it[1], 0)))
        ex.run_all(_stage_task_4, items, lambda item, res: dispatch[item[0]](item, res))
        publisher.flush()


def stage_levels(stages: list[Stage]) -> list[list[Stage]]:
    """Stages grouped by dependency depth (0: needs nothing; k: needs a stage of depth k − 1 at most), each
    group in registry order."""
    depth: dict[str, int] = {}
    for st in stages:
        depth[st.name] = 1 + max((depth[n] for n in st.needs), default=-1)
    return [[st for st in stages if depth[st.name] == d] for d in range(max(depth.values(), default=-1) + 1)]


def _largest_first(items: list, size: Callable) -> list:
    """``items`` by decreasing ``size`` (ties in their given order): the longest tasks go to the pool first, so a
    stage level ends on short tasks and no worker waits on a long one while the other is idle (the next level
    starts only when every task of this one is committed). The ingest keeps the inbox's order: which of two
    re-exports of one recording in the same run is ingested follows it."""
    return [it for _, _, it in sorted((-size(it), i, it) for i, it in enumerate(items))]


def _plan_stage(wh: Warehouse, stage: Stage, stages: list[Stage], sessions, failed_sessions: dict,
                summary: RunSummary) -> tuple[list, dict]:
    """Tasks ``(stage name, session id, params, stamp)`` of ``stage`` for the sessions that want it and are
    stale, and why each runs."""
    items, why = [], {}
    for session_id, study, kind in sessions:
        wanted = why_wanted(stage, kind, study, stages)
        if wanted is None or (stage.applies is not None and not stage.applies(wh.con, session_id)):
            continue
        if session_id in failed_sessions and stage.needs:
            continue
        params = stage_params(study, stage.name, stage.default_params())
        ih = _input_hash(wh, session_id, stage)
        st = stamp(stage, params, ih)
        cur = first(wh.con.execute("SELECT stamp FROM stage_state WHERE session_id = ? AND stage = ?",
                                   [session_id, stage.name]))
        if cur is not None and cur[0] == st:
            summary.skipped_fresh += 1
            continue
        why[session_id] = (ih, f"{wanted}; {_why_stale(wh, session_id, stage, params, ih, cur is not None)}")
        items.append((stage.name, session_id, params, st))
    return items, why


def _commit_stage_result(wh: Warehouse, run_id: str, stage: Stage, why: dict, item, res, failed_sessions: dict,
                         summary: RunSummary, on_progress: Callable[[str], None]) -> None:
    """Record one task's outcome: its rows and stage state in one transaction, or the failure in the ledger."""
    _, inp, params, st = item
    sid = inp.session["session_id"]
    started = _now()
    ph = params_hash(params)
    if isinstance(res, Exception) and (isinstance(res, StorageError) or _storage_problem(res)):
        raise StorageError(f"cannot write the warehouse ({stage.name} {sid}): {res}")
    if isinstance(res, Exception):
        failed_sessions[sid] = str(res)
        summary.failed.append(f"{stage.name} {sid}: {res}")
        with wh.transaction():
            wh.insert("stage_runs", [{"run_id": run_id, "session_id": sid, "stage": stage.name,
                                      "stage_version": stage.version, "params_hash": ph, "stamp": st,
                                      "input_hash": why[sid][0], "reason": why[sid][1],
                                      "status": "failed", "started_at": started, "duration_s": None,
                                      "error": str(res)}])
        on_progress(f"{stage.name} {sid}: FAILED: {res}")
    else:
        out, secs, cpu = res
        with wh.transaction() as con:
            for t in stage.tables:
                rows = out.rows.get(t, [])
                if wh.has_column(t, "producer"):      # a table several stages write
                    con.execute(f'DELETE FROM "{t}" WHERE session_id = ? AND producer = ?', [sid, stage.name])
                    rows = [dict(r, producer=stage.name) for r in rows]
                else:
                    con.execute(f'DELETE FROM "{t}" WHERE session_id = ?', [sid])
                wh.insert(t, rows)
            con.execute("INSERT OR REPLACE INTO stage_state VALUES (?, ?, ?)", [sid, stage.name, st])
            wh.insert("stage_runs", [{"run_id": run_id, "session_id": sid, "stage": stage.name,
                                      "stage_version": stage.version, "params_hash": ph, "stamp": st,
                                      "input_hash": why[sid][0], "reason": why[sid][1],
                                      "status": out.status, "started_at": started, "duration_s": secs, "cpu_s": cpu,
                                      "note": out.note or None}])
        summary.stage_runs += 1
        on_progress(f"{stage.name} {sid}: {out.status} in {secs:.1f} s" + (f" ({out.note})" if out.note else ""))


def _stage_task_4(stage_name, inp, params, st):
    return _stage_task(stage_name, inp, params)


def run(root: Path, inbox: Path | None, *, jobs: int = 1, files: list[Path] | None = None, stages: bool = True,
        command: str = "run", engine: str = "local", scheduler: str | None = None,
        ingest_options: dict | None = None,
        on_progress: Callable[[str], None] = lambda m: None,
        on_phase: Callable[[str, int], None] = _no_phase,
        reports_dir: Path | None = None, build_report: ReportBuilder | None = None,
        replace: list[Path] | None = None, skipped: list[str] | None = None) -> RunSummary:
    """One nightly run (or an ``ingest`` when ``stages`` is False). Holds the run lock throughout.

    With ``build_report`` and ``reports_dir``, the run ends by writing every participant report that is
    missing or stale (pipeline/reports.py); a report that fails counts as a failure of the run.

    ``replace``: files that supersede the recordings they correct (same samples or same file name).
    ``on_phase(name, total)`` announces a phase (ingest, then each level of stages, named "gait + activity"
    etc.: ``stage_levels``) and its number of tasks;
    ``on_progress(message)`` reports each completed task (a committed file or session).
    ``ingest_options``: ``{"session": {...}, "topic_map": {...}}`` for every recording (see ingest.IngestOptions).
    """
    t0 = time.perf_counter()
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    with RunLock(root, command):
        todo = list(files or []) + [Path(f) for f in replace or [] if Path(f) not in set(files or [])]
        skipped = list(skipped or [])
        if inbox is not None and Path(inbox).is_dir():
            recs, skip = inbox_entries(Path(inbox))
            todo += recs
            skipped += [f"{p}: {why}" for p, why in skip]
        ex = make_engine(engine, jobs, scheduler)
        try:
            if todo:
                ex.start()      # the workers start and import while the coordinator opens the warehouse
            summary = _run_locked(root, todo, ex, t0, jobs=jobs, stages=stages, command=command,
                                  ingest_options=ingest_options, on_progress=on_progress, on_phase=on_phase,
                                  reports_dir=reports_dir, build_report=build_report, replace=replace)
            summary.skipped = skipped
            return summary
        finally:
            ex.close()


def _record_failed(wh: Warehouse, run_id: str) -> None:
    """Mark the run failed in the catalog, best effort (the disk may be full)."""
    try:
        with wh.transaction() as con:
            con.execute("UPDATE pipeline_runs SET status = 'failed' WHERE run_id = ?", [run_id])
    except Exception:  # noqa: BLE001 - the error that stopped the run is raised by the caller
        pass


def _run_locked(root: Path, todo: list[Path], ex, t0: float, *, jobs: int, stages: bool, command: str,
                ingest_options, on_progress, on_phase, reports_dir, build_report, replace) -> RunSummary:
    """``run`` with the lock held, the engine made and the files to ingest listed (``todo``)."""
    with Warehouse.open(root) as wh:
        run_id = f"{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}-{uuid.uuid4().hex[:6]}"
        summary = RunSummary(run_id)
        with wh.transaction() as con:
            con.execute("UPDATE pipeline_runs SET status = 'interrupted' WHERE status = 'running'")
            wh.insert("pipeline_runs", [{"run_id": run_id, "command": command, "started_at": _now(),
                                         "status": "running", "jobs": jobs, "version": _version(),
                                         "host": socket.gethostname(), "pid": os.getpid()}])
        wh.gc()
        # the coordinator runs small statements one after another: DuckDB's own worker threads only add
        # scheduling to each (~20 % of a commit's CPU), and the cores belong to the pipeline's workers
        wh.con.execute("SET threads = 1")
        try:
            publisher = _Publisher(wh)
            ingest_files(wh, todo, ex, summary, on_progress, on_phase, ingest_options, replace=replace or (),
                         publisher=publisher)
            if stages:
                run_stages(wh, run_id, ex, summary, on_progress, on_phase=on_phase, publisher=publisher)
            if stages and build_report is not None and reports_dir is not None:
                # on the local engine's workers (already started, imports done); a Dask cluster's
                # workers may not see the reports folder, so there they are built here
                written, failed = write_reports(wh, run_id, Path(reports_dir), build_report, _version(),
                                                on_progress, run_all=ex.run_all if ex.name == "local" else None)
                summary.reports += written
                summary.failed += failed
            status = "failed" if summary.failed else "ok"
        except BaseException:
            status = "failed"
            raise
        finally:
            ex.close()
            summary.seconds = time.perf_counter() - t0
            try:
                with wh.transaction() as con:
                    con.execute("UPDATE pipeline_runs SET finished_at = ?, status = ?, n_ingested = ?, "
                                "n_quarantined = ?, n_stage_runs = ?, n_failed = ? WHERE run_id = ?",
                                [_now(), status, len(summary.ingested), len(summary.quarantined),
                                 summary.stage_runs, len(summary.failed), run_id])
                wh.publish_snapshot()
            except Exception:  # noqa: BLE001 - the original error (e.g. disk full) matters more
                if status == "ok":
                    # the work is committed, but the run ends with an error (exit 2): the ledger must not say
                    # 'ok' (issue #47: the final snapshot copy hitting a full disk was recorded 'ok')
                    _record_failed(wh, run_id)
                    raise
    return summary
