"""The ``stridelab`` command line (DESIGN.md "Command line")."""
from __future__ import annotations

import importlib
from pathlib import Path
import pkgutil

import click

from stridelab.validation import bench as bench_pkg


class _BenchGroup(click.Group):
    """``stridelab bench``: subcommands discovered from ``stridelab.validation.bench.<module>.command``."""

    def _commands(self) -> dict[str, click.Command]:
        found = {}
        for mod in pkgutil.iter_modules(bench_pkg.__path__):
            if mod.name.startswith("_"):
                continue
            m = importlib.import_module(f"stridelab.validation.bench.{mod.name}")
            cmd = getattr(m, "command", None)
            if isinstance(cmd, click.Command):
                found[cmd.name] = cmd
        return found

    def list_commands(self, ctx):
        return sorted(self._commands())

    def get_command(self, ctx, name):
        return self._commands().get(name)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="stridelab")
def main() -> None:
    """StrideLab: wearable-IMU gait and activity pipeline.

    \b
    Examples:
      stridelab demo --no-serve          # simulate a study, run the nightly pipeline
      stridelab simulate inbox/          # write a synthetic study as MCAP files
      stridelab ingest inbox/*.mcap      # load recordings into the warehouse
      stridelab run --jobs 2             # nightly: ingest new files, recompute what is stale
      stridelab bench ingest --json      # ingest speed
    """


@main.group(cls=_BenchGroup)
def bench() -> None:
    """Accuracy and speed benchmarks against public data and reference libraries."""


# ---- shared options -------------------------------------------------------------------------

def _session_options(f):
    f = click.option("--topic-map", "topic_map", multiple=True, metavar="TOPIC=PLACEMENT",
                     help="Map a topic (sensor_msgs/Imu or MagneticField) to a placement; repeatable. "
                          "Also: a [topics] table in the study manifest.")(f)
    return click.option("--session", "session_fields", multiple=True, metavar="FIELD=VALUE",
                        help="Session metadata field for every recording (study, participant, session, kind, "
                             "trial, timezone, ...); repeatable. Must agree with the recording's own metadata.")(f)


def _topic_crc_options(f):
    """``--skip-topic`` and ``--require-crc`` of ``ingest`` and ``run`` (issue #47, docs/integrity.md)."""
    f = click.option("--require-crc", is_flag=True,
                     help="Refuse files not covered by CRCs (MCAP allows writing none; such files are marked "
                          "unverified).")(f)
    return click.option("--skip-topic", "skip_topics", multiple=True, metavar="TOPIC",
                        help="Leave out a topic that looks like IMU/magnetometer data but has no placement (otherwise "
                             "the file is refused); repeatable. The skip is listed with the recording and in the "
                             "run's ingest ledger.")(f)


def _with_topic_crc(options: dict | None, skip_topics, require_crc) -> dict | None:
    """The ingest options with ``--skip-topic``/``--require-crc`` (unchanged when neither is given, so that the
    settings hash of a plain ingest stays the default)."""
    if skip_topics or require_crc:
        return {**(options or {}), "skip_topics": list(skip_topics), "require_crc": require_crc}
    return options


def _ingest_options(session_fields, topic_map) -> dict | None:
    from stridelab.pipeline.console import UserError
    from stridelab.pipeline.session_sources import parse_assignments
    try:
        opts = {"session": parse_assignments(session_fields, "--session"),
                "topic_map": parse_assignments(topic_map, "--topic-map")}
    except ValueError as e:
        raise UserError(str(e)) from None
    bad = [t for t in opts["topic_map"] if not t.startswith("/")]
    if bad:
        raise UserError(f"--topic-map: topic '{bad[0][:60]}' must start with '/'")
    return opts if opts["session"] or opts["topic_map"] else None


def _warehouse_option(f):
    return click.option("--warehouse", "warehouse_dir", type=click.Path(file_okay=False, path_type=Path),
                        default=None, help="Warehouse directory [default: $STRIDELAB_HOME/warehouse].")(f)


def _wh(path: Path | None) -> Path:
    from stridelab.pipeline.config import default_warehouse
    return Path(path) if path else default_warehouse()


def _print_summary(summary, as_json: bool) -> None:
    from stridelab.pipeline.console import emit_json, err_console
    if as_json:
        emit_json(summary.as_dict())
        return
    d = summary.as_dict()
    err_console.print(f"run {d['run_id']}: {d['ingested']} ingested, {d['duplicates']} unchanged, "
                      f"{len(d['reexports'])} re-exports, "
                      f"{len(d['quarantined'])} quarantined, {d['stage_runs']} stage runs, {d['fresh']} up to date, "
                      f"{len(d['failed'])} failed, {len(d['reports'])} reports, {d['seconds']} s")
    for q in d["reexports"]:
        err_console.print(f"  re-export: {safe_text(q)}", markup=False, highlight=False)
    for q in d["quarantined"]:
        err_console.print(f"  quarantined: {safe_text(q)}", markup=False, highlight=False)
    for f in d["failed"]:
        err_console.print(f"  failed: {f}", markup=False)
    for f in d.get("skipped", []):
        err_console.print(f"  skipped: {safe_text(f)}", markup=False, highlight=False)
    for t in d.get("skipped_topics", []):
        err_console.print(f"  skipped topic: {safe_text(t)}", markup=False, highlight=False)


def safe_text(text: str) -> str:
    """``text`` with control characters (newlines, terminal escape codes) shown as escapes: a file name can
    neither forge a log line nor drive the terminal (issue #47)."""
    return "".join(c if c.isprintable() or c == " " else repr(c)[1:-1] for c in str(text))


#: exit codes of ``ingest`` and ``run`` (docs/operations.md "Exit codes"); 2 is ``UserError``/click usage errors
EXIT_OK, EXIT_PROBLEMS, EXIT_COULD_NOT_RUN = 0, 1, 2


def exit_code(summary) -> int:
    """1 when this run quarantined a file, a stage of a session failed or a report could not be written."""
    return EXIT_PROBLEMS if (summary.quarantined or summary.failed) else EXIT_OK


def _run_with_progress(**kw):
    """Run the pipeline with a progress bar per phase (ingest, then each level of stages) on stderr."""
    from stridelab.pipeline.engines import start_workers_early
    start_workers_early(kw.get("engine", "local"), kw.get("jobs", 1), kw.get("scheduler"))   # before the imports below
    import duckdb
    from stridelab.pipeline import runner
    from stridelab.pipeline.console import UserError, err_console, progress
    from stridelab.pipeline.runner import StorageError
    from stridelab.warehouse.lock import WarehouseBusy
    try:
        with progress() as bar:
            current = {"task": None}

            def on_phase(name: str, total: int) -> None:
                if total:
                    current["task"] = bar.add_task(name, total=total)

            def on_progress(msg: str) -> None:
                msg = safe_text(msg)          # a file name with a newline or escape codes forges no log line
                if current["task"] is not None:
                    bar.advance(current["task"])
                if bar.disable:
                    err_console.print(msg, markup=False, highlight=False)
                elif "quarantined" in msg or "re-export" in msg or "FAILED" in msg or "warning" in msg:
                    bar.console.print(msg, markup=False, highlight=False)
            return runner.run(on_progress=on_progress, on_phase=on_phase, **kw)
    except WarehouseBusy as e:
        raise UserError(str(e)) from None
    except (StorageError, OSError, duckdb.Error) as e:
        first_line = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise UserError(f"the run stopped: {first_line}; the previous snapshot is still readable; "
                        f"free disk space or fix the warehouse permissions, then rerun") from None
    except RuntimeError as e:
        if "cannot open the warehouse" in str(e):
            raise UserError(str(e)) from None
        raise


# ---- commands -------------------------------------------------------------------------------

@main.command()
@click.argument("directory", type=click.Path(file_okay=False, path_type=Path))
@click.option("--manifest", type=click.Path(exists=True, path_type=Path), default=None,
              help="Study manifest (TOML) [default: studies/demo/study.toml].")
@click.option("--seed", type=int, default=None, help="Override the manifest's random seed.")
@click.option("--participants", type=click.IntRange(1, 10000), default=None,
              help="Override the number of participants.")
@click.option("--hours", type=click.FloatRange(0.01, 48), default=None,
              help="Override the free-living recording length in hours (default from the manifest: 24).")
@click.option("--jobs", "-j", type=click.IntRange(1, 64), default=None,
              help="Participants simulated in parallel [default: number of cores].")
@click.option("--json", "as_json", is_flag=True, help="Print the files written as JSON.")
def simulate(directory: Path, manifest, seed, participants, hours, jobs, as_json) -> None:
    """Write a synthetic study (MCAP recordings with reference) into DIRECTORY.

    \b
    Examples:
      stridelab simulate stridelab-home/inbox
      stridelab simulate /tmp/inbox --participants 2 --hours 1 --seed 7
    """
    import os
    from stridelab.pipeline.console import UserError, emit_json, err_console
    from stridelab.validation.simulate import simulate_to_dir
    try:
        files = simulate_to_dir(directory, manifest=manifest, seed=seed, participants=participants, hours=hours,
                                jobs=jobs or os.cpu_count() or 1, on_file=lambda p: err_console.print(f"wrote {p}", markup=False, highlight=False))
    except ValueError as e:
        raise UserError(str(e).splitlines()[0]) from None
    if as_json:
        emit_json({"files": [str(f) for f in files]})
    else:
        err_console.print(f"{len(files)} recordings in {directory}")


@main.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))
@_warehouse_option
@click.option("--jobs", "-j", type=click.IntRange(1, 64), default=1, show_default=True, help="Worker processes.")
@_session_options
@click.option("--replace", is_flag=True,
              help="The files are corrections: each supersedes the ingested recording with the same samples or the "
                   "same file name (the next `run` recomputes what depended on it).")
@_topic_crc_options
@click.option("--recover", is_flag=True,
              help="A truncated or damaged MCAP: keep every complete, CRC-valid chunk (a copy under "
                   "WAREHOUSE/recovered/) and ingest that, with what was lost as a warning.")
@click.option("--json", "as_json", is_flag=True, help="Print the outcome as JSON.")
def ingest(paths, warehouse_dir, jobs, session_fields, topic_map, replace, skip_topics, require_crc, recover,
           as_json) -> None:
    """Load recordings (MCAP files, rosbag2 bag directories, or folders holding them) into the
    warehouse; idempotent by content.

    Bad files are quarantined with a one-line reason and do not stop the others.

    \b
    Examples:
      stridelab ingest stridelab-home/inbox
      stridelab ingest session1.mcap session2.mcap --warehouse /data/wh
      stridelab ingest rosbag2_2026_03_02-09_00_00/ --session study=gait2026 --session participant=P001
      stridelab ingest walk.mcap --topic-map /foot_left/imu/data_raw=foot_left
      stridelab ingest walk.mcap --skip-topic /imu/spare --require-crc
      stridelab ingest walk.mcap --topic-map /foot_left/imu=foot_left --replace   # again, on purpose
    """
    from stridelab.pipeline.formats.rosbag2 import is_bag
    from stridelab.pipeline.runner import inbox_entries
    files, skipped = [], []
    for p in paths:
        if p.is_dir() and not is_bag(p):
            recs, skip = inbox_entries(p)
            files += recs
            skipped += [f"{q}: {why}" for q, why in skip]
        else:
            files.append(p)
    options = _with_topic_crc(_ingest_options(session_fields, topic_map), skip_topics, require_crc)   # issue #47
    summary = _run_with_progress(root=_wh(warehouse_dir), inbox=None, files=files, jobs=jobs, stages=False,
                                 command="ingest", ingest_options=options, replace=files if replace else None,
                                 skipped=skipped)
    if recover:
        summary = _recover_damaged(_wh(warehouse_dir), files, options, summary, jobs)
    _print_summary(summary, as_json)
    raise SystemExit(exit_code(summary))


def _recover_damaged(wh: Path, files, options, summary, jobs):
    """``ingest --recover``: the files just quarantined as truncated or damaged are recovered
    (pipeline/recover.py) and the recovered copies ingested; a file recovered counts as handled."""
    import shutil
    from stridelab.pipeline.console import err_console
    from stridelab.pipeline.privacy import stored_name, stored_path
    from stridelab.pipeline.recover import recover, recovered_name
    from stridelab.pipeline.session_sources import sidecar_paths
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(wh)
    if con is None:
        return summary
    try:     # the catalog keeps a keyed hash of each path (stridelab.pipeline.privacy), not the path
        wanted = {stored_path(f): Path(f) for f in files if Path(f).is_file()}
        rows = [(p, r) for p, r in con.execute("SELECT source_path, reason FROM recordings WHERE status = "
                                               "'quarantined'").fetchall() if p in wanted]
    finally:
        con.close()
    marks = ("truncated", "CRC", "corrupt", "runs past", "ends inside", "ends before", "cannot be decompressed")
    for src, reason in rows:
        if not any(m in (reason or "") for m in marks):
            continue
        f = wanted[src]
        out = wh / "recovered" / recovered_name(stored_name(f))     # no operator file name under the warehouse
        rep = recover(f, out)
        err_console.print(f"recover: {rep.summary()}", markup=False, highlight=False)
        if rep.messages_kept == 0:
            continue
        for side in sidecar_paths(f):
            if side.is_file():
                shutil.copyfile(side, sidecar_paths(out)[0])
        opts = dict(options or {}, notes=[f"recovered from a damaged file: {rep.summary(name=stored_name(f))}"])
        again = _run_with_progress(root=wh, inbox=None, files=[out], jobs=jobs, stages=False, command="ingest",
                                   ingest_options=opts)
        if again.ingested:
            summary.quarantined = [q for q in summary.quarantined if not q.startswith(f"{f.name}: ")]
            summary.ingested += again.ingested
        summary.quarantined += again.quarantined
        summary.messages += again.messages
    return summary


@main.command("repair")
@click.argument("paths", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where the recovered files go [default: beside each file, NAME.recovered.mcap].")
@click.option("--json", "as_json", is_flag=True, help="Print what was kept and lost as JSON.")
def repair(paths, out_dir, as_json) -> None:
    """Recover a truncated or damaged MCAP: keep every complete, CRC-valid chunk in a new file and say what was
    lost (chunks, messages, time range). Exit 0 when something was kept, 1 otherwise.

    \b
    Examples:
      stridelab repair logger_2026-03-02.mcap
      stridelab repair inbox/*.mcap --out recovered/ --json
    """
    from stridelab.pipeline.console import emit_json, err_console
    from stridelab.pipeline.recover import recover, recovered_name
    reps = []
    for p in paths:
        out = (out_dir or p.parent) / recovered_name(p)
        reps.append(recover(p, out))
        if not as_json:
            err_console.print(reps[-1].summary() + f" -> {out}", markup=False, highlight=False)
    if as_json:
        emit_json({"files": [r.as_dict() for r in reps]})
    raise SystemExit(0 if all(r.messages_kept for r in reps) else 1)


# ---- integrity: verify / repair (pipeline/verify.py, docs/integrity.md) ------------------------------------

@main.command()
@_warehouse_option
@click.option("--repair", is_flag=True,
              help="Recompute damaged series: raw samples from their recording (found in the inbox or a "
                   "--search folder by its SHA-256), stage outputs at the next `stridelab run`. Takes the run lock.")
@click.option("--search", "search", multiple=True, type=click.Path(exists=True, path_type=Path),
              help="With --repair: a folder (or file) to look for the recordings in, besides the inbox (the "
                   "catalog keeps only a keyed hash of each path). Repeatable.")
@click.option("--json", "as_json", is_flag=True, help="Print the outcome as JSON.")
def verify(warehouse_dir, repair, search, as_json) -> None:
    """Check a whole warehouse: the catalog, every snapshot, and every series file in full (page checksums,
    row counts). Exit 0 when all is well, 1 when something is damaged (and, with --repair, not repaired).

    \b
    Examples:
      stridelab verify
      stridelab verify --repair --warehouse /data/wh --search /data/recordings
    """
    from stridelab.pipeline.console import UserError, emit_json, err_console
    from stridelab.pipeline.verify import verify as run_verify
    from stridelab.warehouse.lock import WarehouseBusy
    try:
        rep = run_verify(_wh(warehouse_dir), repair=repair, search=search)
    except WarehouseBusy as e:
        raise UserError(str(e)) from None
    if as_json:
        emit_json(rep.as_dict())
    else:
        if rep.catalog != "ok":
            err_console.print(f"catalog damaged: {rep.catalog}; recover with `stridelab repair-catalog` "
                              f"(docs/integrity.md)", markup=False, highlight=False)
        for s in rep.snapshots:
            if s["status"] != "ok":
                err_console.print(f"snapshot {s['snapshot']} damaged: {s['status']}", markup=False, highlight=False)
        for d in rep.damaged:
            err_console.print(f"damaged: {d['path']} ({d['detail']})" + (f": {d['repair']}" if d.get("repair") else ""),
                              markup=False, highlight=False)
        err_console.print(f"{rep.checked} series files checked, {len(rep.damaged)} damaged, {len(rep.repaired)} "
                          f"recomputed, {len(rep.scheduled)} recomputed at the next run, {len(rep.unrepaired)} "
                          f"not repairable", markup=False, highlight=False)
    bad = rep.catalog != "ok" or any(s["status"] != "ok" for s in rep.snapshots)
    bad = bad or (bool(rep.unrepaired) if repair else bool(rep.damaged))
    raise SystemExit(1 if bad else 0)


@main.command("repair-catalog")
@_warehouse_option
def repair_catalog(warehouse_dir) -> None:
    """Rebuild a damaged catalog from the newest snapshot that opens (the damaged file is kept beside it); the
    next `stridelab run` ingests again what arrived after that snapshot (docs/integrity.md).

    \b
    Examples:
      stridelab repair-catalog --warehouse /data/wh && stridelab run --inbox /data/inbox --warehouse /data/wh
    """
    from stridelab.pipeline.console import UserError, err_console
    from stridelab.pipeline.recover import rebuild_catalog
    from stridelab.warehouse.lock import WarehouseBusy
    try:
        err_console.print(rebuild_catalog(_wh(warehouse_dir)), markup=False, highlight=False)
    except (WarehouseBusy, RuntimeError) as e:
        raise UserError(str(e).splitlines()[0]) from None


def _format_choices() -> list[str]:
    from stridelab.pipeline.importers import FORMATS
    return sorted([*FORMATS, "c3d"])


@main.command("import")
@click.argument("fmt", metavar="FORMAT", type=click.Choice(_format_choices()))
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--inbox", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where the MCAP files go [default: $STRIDELAB_HOME/inbox].")
@click.option("--study", default=None, help="Study id of the session records [default: imported].")
@click.option("--session", "session_items", multiple=True, metavar="FIELD=VALUE",
              help="Session field (repeatable): participant, session, trial, kind, protocol, timezone, start "
                   "(ISO 8601 time of the first sample for files without a clock).")
@click.option("--placement", default=None, help="Placement of a single-sensor file (e.g. foot_left, chest).")
@click.option("--recording", type=click.Path(path_type=Path), default=None,
              help="c3d only: the recording (.mcap) the markers belong to; the output holds both.")
@click.option("--segment", "segments", multiple=True, metavar="PLACEMENT=M1[,M2,M3]",
              help="c3d only (repeatable): the markers that are the reference of a sensor: M1's path = position "
                   "(e.g. the heel), the M1-M2-M3 cluster = orientation.")
@click.option("--offset-s", type=float, default=0.0, show_default=True,
              help="c3d only: time of the C3D's first frame after the recording's first IMU sample.")
@click.option("--up", type=click.Choice(["z", "y"]), default="z", show_default=True,
              help="c3d only: the capture volume's vertical axis.")
@click.option("--json", "as_json", is_flag=True, help="Print the written files and the errors as JSON.")
def import_cmd(fmt, paths, inbox, study, session_items, placement, recording, segments, offset_s, up,
               as_json) -> None:
    """Convert device exports (FORMAT: xio, gaitmap, uci, broad, apdm, cwa, ...) into recording-format MCAP.

    References the file carries (optical poses, annotated events, activity labels) become reference topics.
    Session fields: format defaults, then a sidecar <file>.session.toml, then --session. A bad file gets one
    line and nothing is written for it; the others go on (exit 1 if any failed).

    \b
    Examples:
      stridelab import xio walk1.csv walk2.csv --placement foot_left --session participant=P07
      stridelab import gaitmap ../shared/data/gaitmap_example --study public
      stridelab import apdm opals.h5 --inbox /data/inbox --session kind=lab --session trial=tug
      stridelab import cwa day1.cwa --placement chest --session participant=P12 --session timezone=Europe/Zurich
      stridelab import c3d walk01.c3d --recording walk01.mcap --segment foot_left=LHEE,LTOE,LMT5 \\
          --segment foot_right=RHEE,RTOE,RMT5 --offset-s 0.25     # markers beside a recording (docs/import.md)
    """
    from stridelab.pipeline.config import default_inbox
    from stridelab.pipeline.console import UserError, emit_json, err_console
    from stridelab.pipeline.importers import ImportRejected, import_paths, parse_session_options
    if fmt == "c3d":
        if study or session_items or placement:
            raise UserError("c3d: the session comes from --recording; --study, --session and --placement do not "
                            "apply (use --segment PLACEMENT=M1,M2,M3)")
        return _import_c3d(paths, recording, segments, offset_s, up, inbox or default_inbox(), as_json)
    if recording or segments:
        raise UserError(f"--recording and --segment are options of 'import c3d', not of '{fmt}'")
    try:
        overrides = parse_session_options(session_items)
    except ImportRejected as e:
        raise UserError(str(e)) from None
    res = import_paths(fmt, paths, inbox or default_inbox(), study=study, session=overrides, placement=placement,
                       on_file=lambda m: None if as_json else err_console.print(m, markup=False, highlight=False))
    if as_json:
        emit_json({"written": [str(p) for p in res.written], "errors": res.errors, "warnings": res.warnings})
    else:
        err_console.print(f"{len(res.written)} recordings written, {len(res.errors)} files refused"
                          + (f", {len(res.warnings)} warnings" if res.warnings else ""), markup=False)
    if res.errors:
        raise SystemExit(1)


def _import_c3d(paths, recording, segments, offset_s, up, inbox, as_json) -> None:
    from stridelab.pipeline.c3d_reference import C3DImportRejected, import_c3d_reference, parse_segments
    from stridelab.pipeline.console import UserError, emit_json, err_console
    if recording is None:
        raise UserError("import c3d: give --recording REC.mcap (the recording the markers belong to)")
    if len(paths) != 1:
        raise UserError("import c3d: give one C3D file (one trial's markers for one --recording)")
    try:
        out = import_c3d_reference(paths[0], recording, inbox, parse_segments(segments), offset_s=offset_s, up=up)
    except C3DImportRejected as e:
        if as_json:
            emit_json({"written": [], "errors": [str(e)]})
            raise SystemExit(1)
        raise UserError(str(e)) from None
    if as_json:
        emit_json({"written": [str(out)], "errors": []})
    else:
        err_console.print(f"wrote {out}", markup=False, highlight=False)


@main.command()
@click.option("--inbox", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Inbox directory scanned for *.mcap [default: $STRIDELAB_HOME/inbox].")
@_warehouse_option
@click.option("--jobs", "-j", type=click.IntRange(1, 64), default=None,
              help="Worker processes [default: number of cores].")
@click.option("--engine", type=click.Choice(["local", "dask"]), default="local", show_default=True,
              help="local: process pool on this machine; dask: Dask distributed (LocalCluster or --scheduler).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Dask scheduler address (tcp://host:8786); workers must see the warehouse directory.")
@click.option("--reports", "reports_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where the run writes every missing or stale participant report [default: $STRIDELAB_HOME/reports].")
@click.option("--no-reports", is_flag=True, help="Do not write participant reports.")
@_session_options
@click.option("--replace", "replace", multiple=True, type=click.Path(exists=True, path_type=Path),
              help="A corrected export (repeatable): it supersedes the ingested recording with the same samples or "
                   "the same file name, and what depended on it is recomputed in this run.")
@_topic_crc_options
@click.option("--json", "as_json", is_flag=True, help="Print the run summary as JSON.")
def run(inbox, warehouse_dir, jobs, engine, scheduler, reports_dir, no_reports, session_fields, topic_map,
        replace, skip_topics, require_crc, as_json) -> None:
    """Nightly run: ingest what is new, recompute what is stale, record a ledger.

    A second run started while one is active refuses with a clear message (exit code 2). Failures of
    one session are recorded in the ledger and do not block the others. Exit codes: 0 all ok, 1 some
    file quarantined or some stage failed, 2 the run could not start or had to stop.

    \b
    Examples:
      stridelab run
      stridelab run --inbox /data/inbox --warehouse /data/wh --jobs 2 --json
      stridelab run --engine dask --scheduler tcp://10.0.0.5:8786
      stridelab run --replace inbox/P001_walk-1_fixed.mcap   # a corrected export supersedes the old one
      stridelab run --require-crc --skip-topic /spare/imu    # strict study; a spare IMU left out on purpose
    """
    import os
    from stridelab.pipeline.config import default_inbox
    if scheduler and engine != "dask":
        from stridelab.pipeline.console import UserError
        raise UserError("--scheduler needs --engine dask")
    from stridelab.pipeline.config import default_reports
    summary = _run_with_progress(root=_wh(warehouse_dir), inbox=inbox or default_inbox(),
                                 jobs=jobs or os.cpu_count() or 1, command="run", engine=engine,
                                 scheduler=scheduler,
                                 ingest_options=_with_topic_crc(_ingest_options(session_fields, topic_map),
                                                                skip_topics, require_crc),
                                 reports_dir=reports_dir or default_reports(),
                                 build_report=None if no_reports else _report_builder(_wh(warehouse_dir)),
                                 replace=list(replace))
    _print_summary(summary, as_json)
    raise SystemExit(exit_code(summary))


def _build_report(wh: Path, study: str, participant: str, out_dir: Path) -> dict:
    from stridelab.reports.participant import build_report
    return build_report(wh, participant, out_dir, study=study)


def _report_builder(wh: Path):
    """The report writer for the runner's report phase (the CLI wires the layers); a partial of a module-level
    function, so the runner can hand it to its worker processes (reports built in parallel)."""
    import functools
    return functools.partial(_build_report, Path(wh))


@main.command()
@click.option("--no-serve", is_flag=True, help="Stop after the pipeline instead of starting the dashboard.")
@click.option("--home", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where the demo study lives [default: $STRIDELAB_HOME].")
@click.option("--port", type=int, default=8501, show_default=True)
@click.option("--jobs", "-j", type=click.IntRange(1, 64), default=None, help="Worker processes [default: cores].")
@click.option("--public", "public_dir", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              help="Instead of simulating, import the public datasets found in DIR (broad, gaitmap_example, "
                   "uci_chest, pyshoe_vicon, voisard_gait, xio_gait) into the study 'public'.")
@click.option("--max-trials", type=click.IntRange(0, 100000), default=4, show_default=True,
              help="With --public: at most N recordings per dataset, spread over it (bounds the run time to a few "
                   "minutes on 2 cores); 0 imports everything.")
def demo(no_serve, home, port, jobs, public_dir, max_trials) -> None:
    """Simulate the demo study (or import public datasets), run the nightly pipeline, then serve the dashboard.

    \b
    Examples:
      stridelab demo               # then open http://localhost:8501
      stridelab demo --no-serve    # pipeline only
      stridelab demo --public ../shared/data --no-serve     # real recordings, 4 per dataset
      stridelab demo --public ../shared/data --max-trials 0  # every recording (slow)
    """
    import os
    from stridelab.pipeline.console import err_console
    from stridelab.validation.simulate import simulate_to_dir
    h = Path(home) if home else None
    if h is not None:
        os.environ["STRIDELAB_HOME"] = str(h.resolve())
    from stridelab.pipeline.config import default_inbox, default_warehouse
    inbox, wh = default_inbox(), default_warehouse()
    existing = sorted(inbox.glob("*.mcap")) if inbox.is_dir() else []
    warming = _start_warm_kernels()
    try:
        if public_dir is not None:
            from stridelab.pipeline.importers import import_public
            res = import_public(public_dir, inbox / "public", max_trials=max_trials or None,
                                on_file=lambda m: err_console.print(f"  {m}", markup=False, highlight=False))
            for e in res.errors:
                err_console.print(f"  refused: {e}", markup=False, highlight=False)
        elif existing:
            err_console.print(f"using the {len(existing)} recordings already in {inbox}")
        else:
            from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
            fl = load_manifest(DEFAULT_MANIFEST).free_living
            err_console.print(f"simulating the demo study into {inbox} (chest days of {fl.hours:g} h from "
                              f"{fl.start_local}, not whole days: studies/demo/study.toml [free_living]) …", markup=False)
            # niced while the warm-up runs: it is one process on the critical path (measured 2026-12-02 03:01 UTC,
            # load 1.0: without it the warm-up ended 13 s after the simulation, one core idle meanwhile)
            simulate_to_dir(inbox, jobs=jobs or os.cpu_count() or 1, nice=5 if warming is not None else 0,
                            on_file=lambda p: err_console.print(f"  wrote {p.name}", markup=False))
        _finish_warm_kernels(warming)
    finally:
        if warming is not None and warming.poll() is None:
            warming.terminate()
    from stridelab.pipeline.config import default_reports
    summary = _run_with_progress(root=wh, inbox=inbox, jobs=jobs or os.cpu_count() or 1, command="demo",
                                 reports_dir=default_reports(), build_report=_report_builder(wh))
    _print_summary(summary, False)
    if no_serve:
        err_console.print(f"warehouse: {wh}")
        return
    _serve(wh, port)


def _start_warm_kernels():
    """``stridelab warm-kernels`` in a second process when this installation's kernels are not compiled yet
    (``make demo`` installs the packages and leaves the compilation to the demo), so that it runs while the
    demo study is simulated instead of before; None when there is nothing to compile."""
    import subprocess
    import sys
    from stridelab.pipeline.console import err_console
    from stridelab.warm import is_warm
    if is_warm():
        return None
    err_console.print("compiling the numba kernels once (stridelab warm-kernels) in a second process, meanwhile:")
    return subprocess.Popen([sys.executable, "-m", "stridelab", "warm-kernels"])


def _finish_warm_kernels(proc) -> None:
    """Wait for the warm-up before the pipeline starts, so that no stage compiles a kernel on the run's clock."""
    from stridelab.pipeline.console import err_console
    if proc is None:
        return
    if proc.wait() != 0:
        err_console.print(f"warning: stridelab warm-kernels failed (exit {proc.returncode}); the stages compile "
                          "their kernels during the run instead (slower)", markup=False)


def _serve(wh: Path, port: int, address: str = "localhost") -> None:
    import os
    import sys
    from stridelab.pipeline.console import err_console
    from importlib.util import find_spec
    app = Path(find_spec("stridelab.dashboard").origin).with_name("app.py")   # dashboard/ in a checkout, installed
    err_console.print(f"dashboard on http://{address}:{port}  (Ctrl+C to stop)")
    cmd = [sys.executable, "-m", "streamlit", "run", str(app), "--server.port", str(port),
           "--server.address", address, "--server.headless", "true", "--browser.gatherUsageStats", "false",
           "--client.toolbarMode", "minimal",
           "--", "--warehouse", str(wh)]
    # Streamlit replaces this process (no child left behind when a service manager or a test sends SIGTERM to
    # the `stridelab dashboard` process: with a child process it stopped the parent and orphaned the server)
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(sys.executable, cmd)


@main.command()
@_warehouse_option
@click.option("--port", type=int, default=8501, show_default=True)
@click.option("--address", default="localhost", show_default=True,
              help="Listen address; keep localhost unless behind an authenticating proxy.")
def dashboard(warehouse_dir, port, address) -> None:
    """Serve the Streamlit dashboard on the warehouse's newest snapshot (read-only).

    \b
    Examples:
      stridelab dashboard
      stridelab dashboard --warehouse /data/wh --port 8600
    """
    _serve(_wh(warehouse_dir), port, address)


@main.command("warm-kernels")
@click.option("--json", "as_json", is_flag=True)
def warm_kernels(as_json) -> None:
    """Compile the pipeline's numba kernels into the installation's shared cache (``make install`` runs it).

    \b
    Examples:
      stridelab warm-kernels          # once after installing; later runs load the kernels
    """
    from stridelab.pipeline.console import emit_json, err_console
    from stridelab.warm import warm
    out = warm()
    if as_json:
        emit_json(out)
    else:
        err_console.print(f"{out['signatures_compiled']} kernel signatures compiled and "
                          f"{out['signatures_from_cache']} loaded from the cache in {out['cache_dir']} "
                          f"({out['kernels']} kernels loaded; the bench-only ones compile on first use)", markup=False)


@main.command("pseudonym-key")
@click.option("--path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Where to create the key [default: $STRIDELAB_PSEUDONYM_KEY or ~/.config/stridelab/pseudonym.key].")
def pseudonym_key(path) -> None:
    """Create the secret key that turns site identifiers into pseudonyms at ingest.

    Keep it outside the warehouse and back it up: without it, new recordings of a participant get
    no longer linked to the same pseudonym.

    \b
    Examples:
      stridelab pseudonym-key
      STRIDELAB_PSEUDONYM_KEY=/secure/key stridelab pseudonym-key
    """
    from stridelab.pipeline.console import UserError, err_console
    from stridelab.pipeline.pseudonym import create_key
    try:
        p = create_key(path)
    except FileExistsError:
        raise UserError(f"a key already exists at {path or 'the default location'}; never replace a key in use") from None
    err_console.print(f"created {p} (mode 600); back it up, keep it out of the warehouse", markup=False)


@main.command()
@click.argument("participant")
@_warehouse_option
@click.option("--study", default=None, help="Study of the participant (needed if the pseudonym exists in several).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Output directory [default: $STRIDELAB_HOME/reports].")
@click.option("--json", "as_json", is_flag=True, help="Print the written paths as JSON.")
def report(participant, warehouse_dir, study, out_dir, as_json) -> None:
    """Per-participant report (self-contained HTML and PDF) from the newest snapshot.

    \b
    Examples:
      stridelab report P001
      stridelab report P003 --study demo --out /tmp/reports --json
    """
    from stridelab.pipeline.config import default_reports
    from stridelab.pipeline.console import UserError, emit_json, err_console
    from stridelab.reports.participant import build_report   # the CLI is the one place that wires every layer
    from stridelab.warehouse.read import snapshot_status
    snap, damaged = snapshot_status(_wh(warehouse_dir))    # a damaged newest snapshot: the previous one, said
    if damaged:
        err_console.print(f"warning: {damaged}", markup=False, highlight=False)
        if snap is None:
            raise UserError(damaged)
    try:
        paths = build_report(_wh(warehouse_dir), participant, out_dir or default_reports(), study=study)
    except (LookupError, ValueError) as e:
        raise UserError(str(e).splitlines()[0]) from None
    if as_json:
        emit_json({k: str(v) for k, v in paths.items()})
    else:
        for k, v in paths.items():
            err_console.print(f"{k}: {v}", markup=False)


# ---- live sessions (pipeline/live; docs/live.md) ----------------------------------------------

@main.command()
@click.option("--replay", type=click.Path(exists=True, path_type=Path), default=None,
              help="Replay a recording-format MCAP file or rosbag2 bag directory.")
@click.option("--speed", default="1", show_default=True, help="Replay speed: a factor (1, 10, …) or 'max'.")
@click.option("--minutes", type=click.FloatRange(0.01, 600), default=None,
              help="Loop the replayed recording until this much time was replayed.")
@click.option("--osc", multiple=True, metavar="PLACEMENT=PORT",
              help="x-io NGIMU sending OSC to this UDP port (repeat per sensor), e.g. --osc foot_left=9001.")
@click.option("--osc-host", default="127.0.0.1", show_default=True, help="Address the NGIMU ports listen on.")
@click.option("--osc-rate", "osc_rate_hz", type=float, default=100.0, show_default=True,
              help="Sample rate the NGIMUs send /sensors at (Hz).")
@click.option("--osc-clock", type=click.Choice(["host", "shared"]), default="host", show_default=True,
              help="shared: the NGIMUs' clocks are synchronised (their time tags share one clock); host: "
                   "each sensor placed by the arrival of its first packet.")
@click.option("--calibration", type=click.Path(exists=True, path_type=Path), default=None,
              help="The session's calibration trial (MCAP or bag): standing + hip FE or straight walking.")
@click.option("--calibration-from", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Use the participant's newest stored calibration in this warehouse (a previous visit).")
@click.option("--participant", default=None, help="Participant pseudonym (default: the replayed file's).")
@click.option("--inbox", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where the session recording goes [default: $STRIDELAB_HOME/inbox].")
@click.option("--name", default=None, help="File name of the recording (without .mcap).")
@click.option("--no-record", is_flag=True, help="Do not record the session.")
@click.option("--recover", is_flag=True, help="Move recordings a crashed session left in INBOX/.live into the inbox.")
@click.option("--compare", type=click.Path(exists=True, path_type=Path), default=None,
              help="A recorded live session: its live outputs against the nightly's offline estimators.")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address of the live page (loopback by default).")
@click.option("--port", type=int, default=8765, show_default=True, help="Port of the live page.")
@click.option("--no-serve", is_flag=True, help="Compute (and record) without serving the page.")
@click.option("--cue", default="stance_asymmetry_pct:0:10", show_default=True, metavar="MEASURE:LOW:HIGH",
              help="Cue when MEASURE leaves [LOW, HIGH]: stance_asymmetry_pct, step_time_asymmetry_pct, "
                   "knee_peak_left, knee_peak_right.")
@click.option("--audio", is_flag=True, help="Cue with sound as well.")
@click.option("--duration", "duration_s", type=float, default=None,
              help="OSC: stop after this many seconds without packets.")
@click.option("--walking-speed", "walking_speed", type=click.FloatRange(0.05, 3.0), default=None, metavar="M_S",
              help="Walking speed for the normative bands (a treadmill's belt speed); default: estimated live.")
@click.option("--leg-length", "leg_length", type=click.FloatRange(0.4, 1.3), default=None, metavar="M",
              help="Leg length of the participant (m), to scale speed (default 0.90 m, shown as assumed).")
@click.option("--json", "as_json", is_flag=True, help="Print the session summary as JSON.")
def live(replay, speed, minutes, osc, osc_host, osc_rate_hz, osc_clock, calibration, calibration_from, participant,
         inbox, name, no_record, recover, compare, host, port, no_serve, cue, audio, duration_s, walking_speed,
         leg_length, as_json) -> None:
    """Real-time session: IMU streams -> joint angles and gait events per sample, a biofeedback page
    (therapist: /, patient: /patient) and the session recorded to the inbox as it arrives.

    \b
    Examples:
      stridelab live --replay inbox/P003_lab1_walk-1.mcap --calibration inbox/P003_lab1_calibration.mcap
      stridelab live --replay bag_dir/ --speed 10 --no-record
      stridelab live --osc pelvis=9000 --osc foot_left=9001 --osc foot_right=9002 --osc-host 0.0.0.0
      stridelab live --recover
      stridelab live --compare inbox/P003_live_x.mcap --calibration inbox/P003_lab1_calibration.mcap --json
    """
    from stridelab.pipeline.config import default_inbox
    from stridelab.pipeline.console import UserError
    from stridelab.pipeline.live.command import print_summary, run_live
    from stridelab.reports.normative import DEFAULT_LEG_LENGTH_M, speed_band_table   # the CLI wires every layer
    inbox = Path(inbox) if inbox else default_inbox()
    if recover:
        from stridelab.pipeline.live.recorder import recover as _recover
        for path, outcome in _recover(inbox):
            click.echo(f"{path}: {outcome}")
        return
    if compare:
        from stridelab.pipeline.console import emit_json
        from stridelab.pipeline.live.agreement import live_vs_offline
        from stridelab.pipeline.live.calibration import calibration_from_trial, calibration_from_warehouse
        try:
            if calibration is not None:
                cal = calibration_from_trial(calibration)
            elif calibration_from is not None and participant:
                cal = calibration_from_warehouse(calibration_from, participant)[0]
            else:
                raise ValueError("--compare needs --calibration TRIAL (or --calibration-from WAREHOUSE --participant)")
            res = live_vs_offline(compare, cal)
        except ValueError as e:
            raise UserError(str(e).splitlines()[0]) from None
        if as_json:
            emit_json(res)
        else:
            for k, v in res["joints"].items():
                click.echo(f"{k}: live - offline RMSE [FE, AA, IE] {v['rmse_deg']} deg")
            for side, ev in res["events"].items():
                for typ, m in ev.items():
                    click.echo(f"{side} {typ}: {m['matched']} of {m['live']} live / {m['offline']} offline matched, "
                               f"live - offline {m['mean_ms']} ± {m['sd_ms']} ms")
        return
    bands = {**speed_band_table(("hip", "knee")), "leg_length_m": leg_length or DEFAULT_LEG_LENGTH_M,
             "leg_length_assumed": leg_length is None, "walking_speed_m_s": walking_speed}
    try:
        summary = run_live(replay=replay, speed=speed, minutes=minutes, osc=osc, osc_host=osc_host,
                           osc_rate_hz=osc_rate_hz, osc_clock=osc_clock, calibration=calibration,
                           calibration_from=calibration_from,
                           participant=participant, inbox=inbox, name=name, record=not no_record, host=host,
                           port=port, serve=not no_serve, cue=cue, audio=audio, bands=bands, duration_s=duration_s,
                           band_note="grey: normative band matched to the walking speed (Schwartz et al. 2008, "
                                     "reports/normative.py)", speed_estimate=walking_speed is None,
                           on_ready=lambda url, src: url and click.echo(f"live page: {url}  (patient: {url}patient)",
                                                                        err=True))
    except ValueError as e:
        raise UserError(str(e).splitlines()[0]) from None
    print_summary(summary, as_json)


# ---- export (tables to CSV/Parquet, recordings to Motion-BIDS; pipeline/export) ---------------------------

@main.group()
def export() -> None:
    """Take results out: a warehouse table to CSV or Parquet, recordings and events to Motion-BIDS.

    \b
    Examples:
      stridelab export table strides strides.parquet
      stridelab export bids stridelab-home/warehouse bids-out/
    """


@export.command("table")
@click.argument("name")
@click.argument("out", type=click.Path(dir_okay=False, path_type=Path))
@_warehouse_option
@click.option("--json", "as_json", is_flag=True, help="Print what was written as JSON.")
def export_table_cmd(name, out, warehouse_dir, as_json) -> None:
    """Write warehouse table NAME (any table; an unknown name lists them) to OUT, a .csv
    or .parquet file, from the newest snapshot.

    \b
    Examples:
      stridelab export table strides strides.csv
      stridelab export table activity_daily /tmp/daily.parquet --warehouse stridelab-home/warehouse
    """
    from stridelab.pipeline.console import UserError, emit_json, err_console
    from stridelab.pipeline.export.tables import export_table
    try:
        r = export_table(_wh(warehouse_dir), name, out)
    except ValueError as e:
        raise UserError(str(e).splitlines()[0]) from None
    if as_json:
        emit_json(r)
    else:
        err_console.print(f"{r['rows']} rows of {r['table']} -> {r['path']}", markup=False)


@export.command("bids")
@click.argument("warehouse", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.argument("out", type=click.Path(file_okay=False, path_type=Path))
@click.option("--study", default=None, help="Only this study.")
@click.option("--participant", "participants", multiple=True, help="Only this participant (repeatable).")
@click.option("--kind", "kinds", multiple=True, type=click.Choice(["lab", "free_living", "calibration"]),
              help="Only sessions of this kind (repeatable); free-living days are large.")
@click.option("--keep-ids", is_flag=True, help="Keep the warehouse's pseudonyms as subject labels "
                                               "[default: renumber sub-01, sub-02, ...].")
@click.option("--subject-map", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the sub-XX -> warehouse pseudonym mapping to this file (keep it out of the export).")
@click.option("--overwrite", is_flag=True, help="Replace OUT if it holds an earlier export.")
@click.option("--author", "authors", multiple=True, help="Dataset author for dataset_description.json (repeatable).")
@click.option("--name", default="StrideLab export", show_default=True, help="Dataset name.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def export_bids_cmd(warehouse, out, study, participants, kinds, keep_ids, subject_map, overwrite, authors, name,
                    as_json) -> None:
    """Write the recordings of WAREHOUSE with their events to OUT as Motion-BIDS (BIDS 1.9), pseudonymised.

    \b
    Examples:
      stridelab export bids stridelab-home/warehouse bids/
      stridelab export bids stridelab-home/warehouse bids-lab/ --kind lab --subject-map key.tsv \
          --author "A. Researcher" --author "B. Clinician" --name "Gait study 2026"
    """
    from stridelab.pipeline.console import UserError, emit_json, err_console
    from stridelab.pipeline.export.bids import export_bids
    try:
        s = export_bids(warehouse, out, study=study, participants=tuple(participants), kinds=tuple(kinds),
                        keep_ids=keep_ids, subject_map=subject_map, overwrite=overwrite, authors=tuple(authors),
                        name=name)
    except ValueError as e:
        raise UserError(str(e).splitlines()[0]) from None
    if as_json:
        emit_json(s.as_dict())
    else:
        err_console.print(f"{s.subjects} subjects, {s.sessions} sessions, {s.recordings} recordings "
                          f"({s.motion_files} motion files, {s.samples} samples, {s.events} events) -> {s.out}",
                          markup=False)
