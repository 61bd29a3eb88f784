"""``stridelab bench pipeline``: a simulated study end to end — wall time, CPU, throughput, memory, scaling.

The study (N participants, each a lab session and one free-living recording of ``--hours`` or ``--days``)
is simulated once into a temporary inbox; then ``stridelab run`` processes it into fresh warehouses in child
processes, with 1 and 2 workers on a subset for the scaling figure and with ``--jobs`` workers on the whole
study. Peak memory is the largest resident set of any process of the run (coordinator or worker); CPU is
user + system time of the whole process tree of the run (Dask's scheduler and workers included, all children of
the run process), split into the coordinator's own (``coordinator_cpu_s``: catalog commits, and on one job the
tasks too) and its children's (``workers_cpu_s``), and into the stage tasks' (``stage_cpu_s_per_participant_day``,
the ledger's ``stage_runs.cpu_s``; per stage in ``stages``) and the rest (``outside_stages_cpu_s_per_participant_day``:
ingest, the coordinator, the workers' start-up); a participant-day is one participant's lab session
and 24 h of free-living recording. ``reading_floor_cpu_s_per_participant_day`` sets that CPU beside what reading
the inbox costs at the least, measured after the run on the first participant's recordings: the SHA-256 of each
file (``content_hash``) and the zstd decompression of its chunks, on one core
(:func:`stridelab.validation.bench.ingest.reading_floor`). A multi-day recording (``--days`` > 2) is made of consecutive simulated
days (day k: the participant's day simulated as session k, shifted by k days) written as one MCAP file.
"""
from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click

from stridelab.pipeline.console import emit_json, err_console


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run(inbox: Path, wh: Path, jobs: int, engine: str) -> dict:
    """Run the pipeline in a child process; wall time, CPU time and the peak RSS of its process tree."""
    cpu0 = _cpu_children()
    t0 = time.perf_counter()
    # the run process's own peak is its VmHWM: ru_maxrss survives exec on Linux, so the child would report the
    # bench's resident size at fork time (6.8 GB after simulating a week in the bench process) as its own
    # the workers start before the runner's imports, as in `stridelab run` (stridelab.pipeline.engines.start_workers_early)
    code = ("import json, resource, sys; from stridelab.pipeline.engines import start_workers_early; "
            "start_workers_early(sys.argv[4], int(sys.argv[3])); from pathlib import Path; from stridelab.pipeline import runner; "
            "s = runner.run(Path(sys.argv[1]), Path(sys.argv[2]), jobs=int(sys.argv[3]), engine=sys.argv[4]); "
            "hwm = [int(l.split()[1]) for l in open('/proc/self/status') if l.startswith('VmHWM:')]; "
            "me, ch = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN); "
            "print(json.dumps({**s.as_dict(), 'peak_child_kb': ch.ru_maxrss, "
            "'peak_self_kb': hwm[0] if hwm else me.ru_maxrss, 'coordinator_cpu_s': me.ru_utime + me.ru_stime, "
            "'workers_cpu_s': ch.ru_utime + ch.ru_stime}))")
    r = subprocess.run([sys.executable, "-c", code, str(wh), str(inbox), str(jobs), engine],
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    cpu = _cpu_children() - cpu0
    if r.returncode != 0:
        raise click.ClickException(f"pipeline run failed: {r.stderr.strip().splitlines()[-1] if r.stderr else r.returncode}")
    out = json.loads(r.stdout.strip().splitlines()[-1])
    out["wall_s"] = wall
    out["cpu_s"] = cpu
    # workers (spawned by the run process: they inherit its small start-up size at most) and the run process
    out["peak_rss_mb"] = max(out.pop("peak_child_kb"), out.pop("peak_self_kb")) / 1024
    return out


def _ledger(wh: Path) -> tuple[int, dict]:
    """IMU samples in the warehouse, and per stage: runs (``ok``), ``skipped`` runs (a session without the
    stage's inputs, with a reason in the ledger), their worker seconds and CPU seconds (``stage_runs.cpu_s``)."""
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(wh)
    try:
        n = int(con.execute("SELECT coalesce(sum(n_samples), 0) FROM sensors WHERE kind = 'imu'").fetchall()[0][0])
        stages = {st: {"runs": int(k), "skipped": int(sk), "worker_s": float(sec or 0.0), "cpu_s": float(cpu or 0.0)}
                  for st, k, sk, sec, cpu in con.execute(
            "SELECT stage, count(*) FILTER (WHERE status = 'ok'), count(*) FILTER (WHERE status = 'skipped'), "
            "sum(duration_s) FILTER (WHERE status IN ('ok', 'skipped')), "
            "sum(cpu_s) FILTER (WHERE status IN ('ok', 'skipped')) FROM stage_runs "
            "WHERE status IN ('ok', 'skipped') GROUP BY 1 ORDER BY 1").fetchall()}
        return n, stages
    finally:
        con.close()


def _drop_page_cache() -> None:
    """Write back dirty pages and drop the page cache (Linux, root): a timed run then reads from disk."""
    os.sync()
    try:
        with open("/proc/sys/vm/drop_caches", "w") as f:
            f.write("3\n")
    except OSError as e:
        raise click.ClickException(f"--drop-caches: cannot write /proc/sys/vm/drop_caches ({e.strerror}); it needs "
                                   f"root on Linux: run the bench as root or leave the option out") from None


def _fingerprint(wh: Path) -> dict:
    """Every table's content hash of the published snapshot (``stridelab.warehouse.catalog.fingerprint``; run ids, times
    and host names excluded), to compare two warehouses built from the same inbox."""
    from stridelab.warehouse.catalog import fingerprint
    from stridelab.warehouse.read import connect_snapshot
    con = connect_snapshot(wh)
    try:
        return fingerprint(con, wh)
    finally:
        con.close()


def _multi_day(directory: Path, participants: int, days: int, jobs: int, manifest=None) -> list[Path]:
    """Each participant's lab session (``manifest``, default the demo study) and one ``days``-day free-living
    recording of the chest IMU (consecutive simulated days)."""
    from dataclasses import replace
    import numpy as np
    from stridelab.estimators.recording import ImuData, Recording
    from stridelab.pipeline.formats.mcap_write import write_recording
    from stridelab.validation.simulate import simulate_to_dir
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.simulator import simulate_chest_day, study_participants
    files = [f for f in simulate_to_dir(directory, manifest=manifest, participants=participants, hours=0.01,
                                        jobs=jobs, visits=1) if "_free" not in f.name]
    for f in directory.glob("*_free*.mcap"):
        f.unlink()
    m = load_manifest(DEFAULT_MANIFEST).with_free_living_hours(24.0)
    m = replace(m, visits=1, free_living=replace(m.free_living, start_local="00:00"))   # whole consecutive days
    for i, p in enumerate(study_participants(m, participants)):
        t, acc, gyr, events = [], [], [], []
        for k in range(days):
            rec, _ = simulate_chest_day(m, p, i, session=k + 1)
            shift = k * 86_400_000_000_000
            imu = rec.imu["chest"]
            t.append(imu.t_ns + shift)
            acc.append(imu.acc)
            gyr.append(imu.gyr)
            events += [{**e, "t_ns": e["t_ns"] + shift, **({"end_ns": e["end_ns"] + shift} if "end_ns" in e else {})}
                       for e in rec.events]
            md = rec.metadata
            del rec, imu
        md = {**md, "session": f"{p.id}-free-living-1", "trial": f"days-1-{days}"}
        rec = Recording(metadata=md, imu={"chest": ImuData(np.concatenate(t), np.concatenate(acc), np.concatenate(gyr))},
                        events=events, name=f"{p.id}_free1_days-{days}")
        del t, acc, gyr
        files.append(write_recording(rec, directory / f"{rec.name}.mcap"))
        del rec
    return files


_STUDY_FILE = ".bench-study.json"


def _chest_only_manifest(tmp: Path) -> Path:
    """The demo study's manifest without its lower-back IMU (``[lab] lower_back`` and ``[free_living] lower_back``
    false): the study the pipeline's 60 s night was set on before the trunk-gait stage (docs/operations.md)."""
    import re
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    text, n = re.subn(r"(?m)^lower_back\s*=\s*true\b", "lower_back = false", DEFAULT_MANIFEST.read_text())
    path = tmp / "chest-only-study.toml"
    path.write_text(text)
    m = load_manifest(path)
    if n == 0 or m.lab.lower_back or m.free_living.lower_back:
        raise click.ClickException(f"{DEFAULT_MANIFEST}: could not switch its lower-back IMU off for --no-lower-back")
    return path


def _reuse(inbox: Path, participants: int, hours: float, lower_back: bool = True) -> list[Path] | None:
    """The recordings of a study simulated earlier into ``inbox`` by this bench with the same size and sensors, or
    None when there is none yet; a folder holding another study (or anything else) is refused."""
    if not inbox.exists() or not any(inbox.iterdir()):
        return None
    meta = inbox / _STUDY_FILE
    if not meta.is_file():
        raise click.ClickException(f"{inbox}: not a study simulated by this bench (no {_STUDY_FILE}); "
                                   "give an empty or new folder to --inbox")
    m = json.loads(meta.read_text())
    if (m["participants"], m["hours"]) != (participants, hours):
        raise click.ClickException(f"{inbox}: holds {m['participants']} participants x {m['hours']} h, not "
                                   f"{participants} x {hours} h; use another --inbox folder")
    if m.get("lower_back", True) != lower_back:
        have, want = (("with" if x else "without") for x in (m.get("lower_back", True), lower_back))
        raise click.ClickException(f"{inbox}: holds a study {have} the lower-back sensor, not {want} it; "
                                   "use another --inbox folder")
    files = [inbox / f for f in m["files"]]
    if not all(f.is_file() for f in files):
        raise click.ClickException(f"{inbox}: recordings are missing; delete the folder to simulate again")
    return files


@click.command("pipeline")
@click.option("--participants", "-n", type=click.IntRange(1, 1000), default=20, show_default=True)
@click.option("--hours", type=click.FloatRange(0.01, 48), default=24.0, show_default=True,
              help="Length of each free-living recording.")
@click.option("--days", type=click.IntRange(1, 14), default=None,
              help="Free-living recordings of this many days (overrides --hours; > 2: consecutive simulated days).")
@click.option("--jobs", "-j", type=click.IntRange(1, 64), default=2, show_default=True)
@click.option("--scaling-participants", type=click.IntRange(0, 1000), default=4, show_default=True,
              help="Study size for the 1-vs-2-worker speed-up (0: skip it).")
@click.option("--engine", type=click.Choice(["local", "dask"]), default="local", show_default=True)
@click.option("--compare-engines", is_flag=True,
              help="Also run the whole study on the other engine (dask if --engine local) into a second warehouse: "
                   "its wall time, the ratio to the first, and whether the two warehouses are identical.")
@click.option("--workdir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where the bench's warehouses are built (created if missing) [default: the system temp dir].")
@click.option("--inbox", "keep_inbox", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Keep the simulated study in this folder and reuse it on the next run with the same "
                   "--participants/--hours/--days (simulating 20 participant-days takes about 5 min).")
@click.option("--lower-back/--no-lower-back", default=True, show_default=True,
              help="Simulate the demo study with its belt-worn lower-back IMU (lab visits and home days), or the "
                   "chest-only study on which the 60 s night of issues 19 and 45 was set.")
@click.option("--drop-caches", is_flag=True,
              help="Write back and drop the page cache before every timed run (root only), so the recordings are "
                   "read from disk as in a real night and runs are comparable; JSON key page_cache_dropped.")
@click.option("--json", "as_json", is_flag=True)
def command(participants, hours, days, jobs, scaling_participants, engine, compare_engines, workdir,
            keep_inbox, lower_back, drop_caches, as_json) -> None:
    """End-to-end pipeline on a simulated study: wall time, CPU per participant-day, samples/s, peak memory,
    1→2 worker speed-up.

    \b
    Examples:
      stridelab bench pipeline --participants 20 --json
      stridelab bench pipeline --days 7 --participants 1 --jobs 1 --json
      stridelab bench pipeline -n 4 --hours 2 --engine dask
      stridelab bench pipeline --participants 20 --compare-engines --json
      stridelab bench pipeline --participants 20 --inbox /tmp/study20 --json   # simulate once, rerun on it
      sudo stridelab bench pipeline --participants 20 --inbox /tmp/study20 --drop-caches --json
      stridelab bench pipeline --participants 20 --no-lower-back --inbox /tmp/study20c --json   # chest only
    """
    from stridelab.validation.bench.ingest import reading_floor
    from stridelab.validation.simulate import simulate_to_dir
    if days is not None:
        hours = 24.0 * days
    if workdir is not None:
        try:
            workdir.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise click.ClickException(f"--workdir {workdir}: cannot create it ({e.strerror}); choose a writable folder")
    if drop_caches:
        _drop_page_cache()                  # refuse before minutes of simulation, not after
    before_run = _drop_page_cache if drop_caches else (lambda: None)
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        inbox = tmp / "inbox" if keep_inbox is None else Path(keep_inbox)
        files = _reuse(inbox, participants, hours, lower_back) if keep_inbox is not None else None
        manifest = None if lower_back else _chest_only_manifest(tmp)
        if files is not None:
            sim_s = None
            err_console.print(f"reusing the {len(files)} simulated recordings in {inbox}")
        else:
            if hours <= 48.0:
                files = simulate_to_dir(inbox, manifest=manifest, participants=participants, hours=hours, jobs=jobs,
                                        visits=1)
            else:
                files = _multi_day(inbox, participants, int(days), jobs, manifest)
            sim_s = time.perf_counter() - t0
            if keep_inbox is not None:
                (inbox / _STUDY_FILE).write_text(json.dumps({"participants": participants, "hours": hours,
                                                             "lower_back": lower_back,
                                                             "files": sorted(f.name for f in files)}))
            err_console.print(f"simulated {len(files)} recordings of {participants} participants in {sim_s:.0f} s")
        k = min(scaling_participants, participants)
        sub = tmp / "inbox_sub"
        sub.mkdir()
        pids = sorted({f.name.split("_")[0] for f in files})[:k]
        for f in files:
            if f.name.split("_")[0] in pids:
                (sub / f.name).symlink_to(f)
        scaling = {}
        for j in ((1, 2) if k else ()):
            err_console.print(f"scaling run: {k} participants, {j} worker(s) …")
            before_run()
            scaling[j] = _run(sub, tmp / f"wh_sub{j}", j, engine)
        err_console.print(f"full run: {participants} participants, {jobs} workers …")
        before_run()
        full = _run(inbox, tmp / "wh", jobs, engine)
        n, stages = _ledger(tmp / "wh")
        pdays = participants * hours / 24.0
        out = {
            "participants": participants, "recorded_days_per_participant": hours / 24.0, "recordings": len(files),
            "lower_back": lower_back,
            "imu_samples": n, "simulate_s": sim_s, "run_wall_s": full["wall_s"], "jobs": jobs, "engine": engine,
            "cpu_s": full["cpu_s"], "cpu_s_per_participant_day": full["cpu_s"] / pdays,
            "wall_s_per_recorded_day": full["wall_s"] / pdays,
            "samples_per_s": n / full["wall_s"], "peak_rss_mb": full["peak_rss_mb"],
            "coordinator_cpu_s": full["coordinator_cpu_s"], "workers_cpu_s": full["workers_cpu_s"],
            "stages": stages, "failed": full["failed"], "page_cache_dropped": drop_caches,
        }
        # the CPU split: the stages' tasks (the ledger's cpu_s) and everything else (ingest, coordinator, start-up)
        out["stage_cpu_s_per_participant_day"] = sum(v["cpu_s"] for v in stages.values()) / pdays
        out["outside_stages_cpu_s_per_participant_day"] = (out["cpu_s_per_participant_day"]
                                                           - out["stage_cpu_s_per_participant_day"])
        # what the inbox itself costs to read, for scale: the first participant's recordings, per recorded day
        p0 = min(f.name.split("_")[0] for f in files)
        out["reading_floor_cpu_s_per_participant_day"] = reading_floor(
            [f for f in files if f.name.split("_")[0] == p0]) / (hours / 24.0)
        err_console.print(f"CPU per participant-day {out['cpu_s_per_participant_day']:.2f} s: stages "
                          f"{out['stage_cpu_s_per_participant_day']:.2f} s, ingest, coordinator and start-up "
                          f"{out['outside_stages_cpu_s_per_participant_day']:.2f} s, of which no ingest can "
                          f"avoid {out['reading_floor_cpu_s_per_participant_day']:.2f} s (SHA-256 of the files and "
                          f"zstd decompression of their chunks, one core, {p0}'s recordings)")
        if compare_engines:
            other = "dask" if engine == "local" else "local"
            first_fp = _fingerprint(tmp / "wh")
            # the first warehouse's series files leave before the second run (as in the first run, only the
            # inbox and the run's own warehouse compete for the page cache: 20 participant-days are 13.5 GB of
            # recordings and 8.2 GB of series, on a 24 GB machine)
            shutil.rmtree(tmp / "wh" / "series", ignore_errors=True)
            err_console.print(f"full run on the {other} engine: {participants} participants, {jobs} workers …")
            before_run()
            alt = _run(inbox, tmp / "wh_other", jobs, other)
            out["engines"] = {engine: {"run_wall_s": full["wall_s"], "cpu_s": full["cpu_s"],
                                       "peak_rss_mb": full["peak_rss_mb"]},
                              other: {"run_wall_s": alt["wall_s"], "cpu_s": alt["cpu_s"],
                                      "peak_rss_mb": alt["peak_rss_mb"], "failed": alt["failed"]},
                              f"{other}_over_{engine}_wall": alt["wall_s"] / full["wall_s"],
                              "identical_warehouse": first_fp == _fingerprint(tmp / "wh_other")}
        if k:
            out["scaling"] = {"participants": k, "wall_s_1_worker": scaling[1]["wall_s"],
                              "wall_s_2_workers": scaling[2]["wall_s"],
                              "speedup_1_to_2": scaling[1]["wall_s"] / scaling[2]["wall_s"],
                              "peak_rss_mb_1_worker": scaling[1]["peak_rss_mb"],
                              "peak_rss_mb_2_workers": scaling[2]["peak_rss_mb"]}
    if as_json:
        emit_json(out)
    else:
        err_console.print(out)
