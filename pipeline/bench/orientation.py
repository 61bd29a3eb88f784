"""``stridelab bench orientation``: accuracy and speed of the orientation estimators on BROAD.

Every estimator of ``estimators.orientation.ESTIMATORS`` and of ``REPLICATION`` (the thesis' literal LKF, scored
but not selectable by the pipeline), or those named with ``--estimator``, runs on
every BROAD trial, 9D (magnetometer used), with its default parameters; no per-trial alignment. The
error quaternion ``q_est ⊗ q_ref*`` (earth frame) is split into total / heading / inclination angles
and RMS'd over the trial's ``movement`` mask (``estimators.orientation.evaluation``). Speed is the
wall time of the estimator call divided by the number of samples, after one warm-up call (numba JIT).
vqf (online) and offline vqf run in the same process for comparison. ``--pso FILTER:LEVELS`` instead tunes
Madgwick / Mahony switching gains by particle swarm with leave-trials-out CV (:func:`run_pso_tuning`).
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
    from estimators.orientation import DEFAULT_OFFLINE, DEFAULT_ONLINE, ESTIMATORS, REPLICATION
    from estimators.orientation.evaluation import orientation_rmse_deg
    from pipeline.formats.broad import load_broad

    ESTIMATORS = {**ESTIMATORS, **REPLICATION}
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
              help="estimator name (repeatable); default: all registered estimators and the replication-only "
                   "ones (estimators.orientation.REPLICATION)")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
@click.option("--pso", "pso", default=None, metavar="FILTER:LEVELS",
              help="instead of the benchmark, tune madgwick|mahony switching gains (1 = fixed, 2 = VST1, 3 = VST2) by "
                   "particle swarm with 3-fold leave-trials-out CV, e.g. --pso madgwick:2")
@click.option("--pso-particles", default=50, show_default=True, help="swarm size (thesis: 50)")
@click.option("--pso-iter", default=50, show_default=True, help="PSO iterations (thesis: 50)")
@click.option("--no-cv", is_flag=True, help="with --pso: skip the cross-validation, tune on all trials only")
def command(broad: Path, estimators: tuple[str, ...], as_json: bool, pso: str | None, pso_particles: int,
            pso_iter: int, no_cv: bool) -> None:
    """Orientation accuracy (RMSE vs optical reference, degrees) and speed on BROAD.

    \b
    Examples:
      stridelab bench orientation
      stridelab bench orientation --estimator dcf --estimator vqf --json
      stridelab bench orientation --broad /data/broad --json > broad.json
      stridelab bench orientation --pso madgwick:2 --json      # particle-swarm tuning + CV
    """
    from estimators.orientation import ESTIMATORS, REPLICATION
    if not broad.exists():
        raise UserError(f"BROAD data not found at {broad}; pass --broad DIR (see DESIGN.md 'Real data')")
    if pso:
        filt, _, lv = pso.partition(":")
        if filt not in ("madgwick", "mahony") or lv not in ("1", "2", "3"):
            raise UserError(f"--pso expects madgwick|mahony:1|2|3, got {pso!r}")
        res = run_pso_tuning(broad, filt, int(lv), n_particles=pso_particles, n_iter=pso_iter, cv=not no_cv)
        if as_json:
            emit_json(res)
        else:
            cv = res.get("cv", {}).get("cv_heldout_mean_deg")
            click.echo(f"{filt} {lv}-level: all-trials mean RMSE {res['all_trials']['train_cost_deg']:.3f}°"
                       + (f", leave-trials-out held-out {cv:.3f}°" if cv is not None else "")
                       + f", {res['all_trials']['seconds']:.0f} s; params {res['all_trials']['params']}")
        return
    names = list(dict.fromkeys(estimators)) or list(ESTIMATORS) + list(REPLICATION)
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


def run_pso_tuning(broad: Path, filter_name: str, n_levels: int, *, n_particles: int = 50, n_iter: int = 50,
                   cv: bool = True, seed: int = 0) -> dict:
    """Particle-swarm tuning of Madgwick / Mahony switching gains on BROAD (estimators.orientation.pso):
    leave-trials-out CV (3 folds, trial k in fold k mod 3) for the honest held-out error, then one run on all
    trials whose result is what tuned_gains.json ships. Returns a JSON-able dict with timings."""
    import dataclasses

    from estimators.orientation.pso import SwarmData, SwitchingSpace, pso_leave_trials_out, tune_pso
    from pipeline.formats.broad import load_broad
    try:
        trials = load_broad(broad)
    except ValueError as e:
        raise UserError(str(e)) from e
    space = SwitchingSpace(filter_name, n_levels)
    data = SwarmData.from_trials(trials)
    out = {"filter": filter_name, "n_levels": n_levels, "space": list(space.names), "n_particles": n_particles,
           "n_iter": n_iter, "trials": list(data.names)}
    kw = dict(n_particles=n_particles, n_iter=n_iter, seed=seed)
    if cv:
        t0 = time.perf_counter()
        r = pso_leave_trials_out(space, data, **kw)
        out["cv"] = {"heldout_deg": [float(v) for v in r["heldout_deg"]],
                     "cv_heldout_mean_deg": r["cv_heldout_mean_deg"], "folds": r["folds"],
                     "seconds": time.perf_counter() - t0}
    t = tune_pso(space, data, **kw)
    out["all_trials"] = {"params": dataclasses.asdict(t.params), "train_cost_deg": t.train_cost_deg,
                         "seconds": t.seconds, "n_evaluations": t.n_evaluations,
                         "history": [float(v) for v in t.history]}
    return out
