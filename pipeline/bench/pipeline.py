"""``stridelab bench pipeline``: a simulated study end to end — wall time, throughput, memory, scaling.

The study (N participants, each a lab session and one free-living day) is simulated once into a
temporary inbox; then ``stridelab run`` processes it into fresh warehouses in child processes, with
1 and 2 workers on a subset for the scaling figure and with ``--jobs`` workers on the whole study.
Peak memory is the largest resident set of any process of the run (coordinator or worker).
"""
from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click

from pipeline.console import emit_json, err_console


def _run(inbox: Path, wh: Path, jobs: int, engine: str) -> dict:
    """Run the pipeline in a child process; wall time and the peak RSS of its process tree."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    code = ("import json, resource, sys; from pathlib import Path; from pipeline import runner; "
            "s = runner.run(Path(sys.argv[1]), Path(sys.argv[2]), jobs=int(sys.argv[3]), engine=sys.argv[4]); "
            "print(json.dumps({**s.as_dict(), 'peak_child_kb': resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss}))")
    r = subprocess.run([sys.executable, "-c", code, str(wh), str(inbox), str(jobs), engine],
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise click.ClickException(f"pipeline run failed: {r.stderr.strip().splitlines()[-1] if r.stderr else r.returncode}")
    out = json.loads(r.stdout.strip().splitlines()[-1])
    own = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    out["wall_s"] = wall
    out["peak_rss_mb"] = max(out.pop("peak_child_kb"), own if own > before else 0) / 1024
    return out


def _samples(wh: Path) -> int:
    from warehouse.read import connect_snapshot
    con = connect_snapshot(wh)
    try:
        return int(con.execute("SELECT coalesce(sum(n_samples), 0) FROM sensors WHERE kind = 'imu'").fetchall()[0][0])
    finally:
        con.close()


@click.command("pipeline")
@click.option("--participants", "-n", type=click.IntRange(1, 1000), default=20, show_default=True)
@click.option("--hours", type=click.FloatRange(0.01, 48), default=24.0, show_default=True,
              help="Length of each free-living recording.")
@click.option("--jobs", "-j", type=click.IntRange(1, 64), default=2, show_default=True)
@click.option("--scaling-participants", type=click.IntRange(1, 1000), default=4, show_default=True,
              help="Study size for the 1-vs-2-worker speed-up.")
@click.option("--engine", type=click.Choice(["local", "dask"]), default="local", show_default=True)
@click.option("--workdir", type=click.Path(file_okay=False, path_type=Path), default=None)
@click.option("--json", "as_json", is_flag=True)
def command(participants, hours, jobs, scaling_participants, engine, workdir, as_json) -> None:
    """End-to-end pipeline on a simulated study: wall time, samples/s, peak memory, 1→2 worker speed-up.

    \b
    Examples:
      stridelab bench pipeline --participants 20 --json
      stridelab bench pipeline -n 4 --hours 2 --engine dask
    """
    from pipeline.simulate import simulate_to_dir
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        files = simulate_to_dir(tmp / "inbox", participants=participants, hours=hours, jobs=jobs)
        sim_s = time.perf_counter() - t0
        err_console.print(f"simulated {len(files)} recordings of {participants} participants in {sim_s:.0f} s")
        k = min(scaling_participants, participants)
        sub = tmp / "inbox_sub"
        sub.mkdir()
        pids = sorted({f.name.split("_")[0] for f in files})[:k]
        for f in files:
            if f.name.split("_")[0] in pids:
                (sub / f.name).symlink_to(f)
        scaling = {}
        for j in (1, 2):
            err_console.print(f"scaling run: {k} participants, {j} worker(s) …")
            scaling[j] = _run(sub, tmp / f"wh_sub{j}", j, engine)
        err_console.print(f"full run: {participants} participants, {jobs} workers …")
        full = _run(tmp / "inbox", tmp / "wh", jobs, engine)
        n = _samples(tmp / "wh")
        out = {
            "participants": participants, "recordings": len(files), "imu_samples": n,
            "simulate_s": sim_s, "wall_s": full["wall_s"], "jobs": jobs, "engine": engine,
            "samples_per_s": n / full["wall_s"], "peak_rss_mb": full["peak_rss_mb"],
            "failed": full["failed"],
            "scaling": {"participants": k, "wall_s_1_worker": scaling[1]["wall_s"],
                        "wall_s_2_workers": scaling[2]["wall_s"],
                        "speedup_1_to_2": scaling[1]["wall_s"] / scaling[2]["wall_s"],
                        "peak_rss_mb_1_worker": scaling[1]["peak_rss_mb"],
                        "peak_rss_mb_2_workers": scaling[2]["peak_rss_mb"]},
        }
    if as_json:
        emit_json(out)
    else:
        err_console.print(out)
