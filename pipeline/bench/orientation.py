"""``stridelab bench orientation``: accuracy and speed of the orientation estimators on BROAD.

Every estimator of ``estimators.orientation.ESTIMATORS`` (or those named with ``--estimator``) runs on
every BROAD trial, 9D (magnetometer used), with its default parameters; no per-trial alignment. The
error quaternion ``q_est ⊗ q_ref*`` (earth frame) is split into total / heading / inclination angles
and RMS'd over the trial's ``movement`` mask (``estimators.orientation.evaluation``). Speed is the
wall time of the estimator call divided by the number of samples, after one warm-up call (numba JIT).
vqf (online) and offline vqf run in the same process for comparison.
"""
from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np

from pipeline.console import UserError, emit_json, err_console, progress

PROJECT_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_BROAD = PROJECT_ROOT.parent / "shared" / "data" / "broad"


def run_benchmark(broad: Path, names: list[str], *, show_progress: bool = True) -> dict:
    """Run the benchmark; returns the JSON-able result (see module docstring)."""
    from estimators.orientation import DEFAULT_OFFLINE, DEFAULT_ONLINE, ESTIMATORS
    from estimators.orientation.evaluation import orientation_rmse_deg
    from pipeline.formats.broad import load_broad

    unknown = [n for n in names if n not in ESTIMATORS]
    if unknown:
        raise UserError(f"unknown estimator(s) {', '.join(unknown)}; choose from {', '.join(sorted(ESTIMATORS))}")
    try:
        trials = load_broad(broad)
    except ValueError as e:
        raise UserError(str(e)) from e
    rows, summary = [], {}
    with progress(show_progress) as p:
        task = p.add_task("orientation", total=len(names) * len(trials))
        for name in names:
            est = ESTIMATORS[name]
            t0 = trials[0]
            k = int(2 * t0.sampling_rate_hz)
            est(t0.gyr[:k], t0.acc[:k], t0.mag[:k], sampling_rate_hz=t0.sampling_rate_hz)   # warm-up / JIT
            seconds, samples, errs = 0.0, 0, []
            for tr in trials:
                p.update(task, description=f"{name}: {tr.name}")
                t1 = time.perf_counter()
                res = est(tr.gyr, tr.acc, tr.mag, sampling_rate_hz=tr.sampling_rate_hz)
                seconds += time.perf_counter() - t1
                samples += len(tr.gyr)
                e = orientation_rmse_deg(res.quat, tr.quat_ref, tr.movement)
                rows.append({"trial": tr.name, "estimator": name, "total_rmse_deg": e.total_rmse_deg,
                             "heading_rmse_deg": e.heading_rmse_deg, "inclination_rmse_deg": e.inclination_rmse_deg})
                errs.append(e.total_rmse_deg)
                p.advance(task)
            summary[name] = {"mean_total_rmse_deg": float(np.mean(errs)), "us_per_sample": 1e6 * seconds / samples}
    return {"trials": rows, "summary": summary, "default": DEFAULT_ONLINE, "default_offline": DEFAULT_OFFLINE}


@click.command("orientation")
@click.option("--broad", "broad", type=click.Path(path_type=Path), default=DEFAULT_BROAD, show_default=True,
              help="folder of BROAD *.hdf5 trials (or one file)")
@click.option("--estimator", "estimators", multiple=True,
              help="estimator name (repeatable); default: all registered estimators")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(broad: Path, estimators: tuple[str, ...], as_json: bool) -> None:
    """Orientation accuracy (RMSE vs optical reference, degrees) and speed on BROAD.

    \b
    Examples:
      stridelab bench orientation
      stridelab bench orientation --estimator dcf --estimator vqf --json
      stridelab bench orientation --broad /data/broad --json > broad.json
    """
    from estimators.orientation import ESTIMATORS
    if not broad.exists():
        raise UserError(f"BROAD data not found at {broad}; pass --broad DIR (see DESIGN.md 'Real data')")
    names = list(dict.fromkeys(estimators)) or list(ESTIMATORS)
    result = run_benchmark(broad, names, show_progress=not as_json or err_console.is_terminal)
    if as_json:
        emit_json(result)
        return
    from rich.table import Table
    t = Table(title=f"BROAD orientation ({len({r['trial'] for r in result['trials']})} trials, 9D, movement mask)")
    for c in ("estimator", "mean total RMSE (°)", "µs/sample"):
        t.add_column(c, justify="left" if c == "estimator" else "right")
    for name, s in sorted(result["summary"].items(), key=lambda kv: kv[1]["mean_total_rmse_deg"]):
        tag = " (default)" if name == result["default"] else (" (default offline)" if name == result["default_offline"]
                                                             else "")
        t.add_row(name + tag, f"{s['mean_total_rmse_deg']:.3f}", f"{s['us_per_sample']:.2f}")
    from rich.console import Console
    Console().print(t)
