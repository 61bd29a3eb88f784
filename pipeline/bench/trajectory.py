"""``stridelab bench trajectory``: walked distance and final position error of loop walks (foot IMU CSVs).

Each file (``pipeline.formats.loop_csv``) goes through ``estimators.gait.foot_kinematics`` (ESKF + ZUPT + RTS,
default parameters, mounting-agnostic). distance_m = Σ horizontal displacement between consecutive mid-stances;
final_position_error_m = |p(last mid-stance) − p(first mid-stance)| (3-D; the walk ends where it started),
also horizontal (``final_position_error_xy_m``) and as % of distance.
"""
from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from pipeline.console import UserError, emit_json, err_console, progress


def evaluate_loop(path: Path) -> dict:
    """Distance and closure error of one loop CSV (module docstring)."""
    from estimators.gait import foot_kinematics
    from pipeline.formats.loop_csv import load_loop_csv
    try:
        rec = load_loop_csv(path)
        fk = foot_kinematics(rec.gyr, rec.acc, sampling_rate_hz=rec.sampling_rate_hz)
    except ValueError as e:
        raise UserError(f"{path}: {e}") from e
    row = {"file": str(path), "sampling_rate_hz": rec.sampling_rate_hz, "status": fk.status}
    mids = fk.mid_stance
    if fk.status == "no_stance" or len(mids) < 2:
        row.update(distance_m=None, final_position_error_m=None, final_position_error_xy_m=None, n_stances=len(mids))
        return row
    p = fk.trajectory.pos[mids]
    dist = float(np.sum(np.hypot(*np.diff(p[:, :2], axis=0).T)))
    err = p[-1] - p[0]
    row.update(distance_m=dist, final_position_error_m=float(np.linalg.norm(err)),
               final_position_error_xy_m=float(np.hypot(err[0], err[1])),
               error_pct_of_distance=float(100 * np.linalg.norm(err) / dist) if dist > 0 else None,
               n_stances=int(len(mids)))
    return row


@click.command("trajectory")
@click.option("--loop", "loops", multiple=True, required=True, type=click.Path(path_type=Path),
              help="loop-walk CSV (repeatable; the foot ends where it started)")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(loops: tuple[Path, ...], as_json: bool) -> None:
    """Walked distance and final position error (m) of foot-IMU loop walks, in the order given.

    \b
    Examples:
      stridelab bench trajectory --loop walk1.csv --loop walk2.csv --json
    """
    for p in loops:
        if not p.is_file():
            raise UserError(f"loop file not found: {p}")
    rows = []
    with progress(not as_json or err_console.is_terminal) as pr:
        task = pr.add_task("trajectory", total=len(loops))
        for p in loops:
            pr.update(task, description=f"{p.name}")
            rows.append(evaluate_loop(p))
            pr.advance(task)
    if as_json:
        emit_json({"files": rows})
        return
    for r in rows:
        click.echo(f"{r['file']}: distance {r['distance_m']} m, final position error {r['final_position_error_m']} m")
