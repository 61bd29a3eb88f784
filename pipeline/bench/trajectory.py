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


DS_METHODS = ("zupt_only", "zupt_height", "ds21", "ds9_table1", "ds9_true")


def duong_suh_benchmark(seeds: int = 10, *, pitch_deg: float = 0.0) -> dict:
    """Spec B11/B12 on the synthetic walk of ``estimators.trajectory._sim_ds`` (B11 configuration; the filters start
    from the Table 1 geometry, the truth is eq. (24)): mean over seeds of the per-run RMS error per axis (m), for
    ZUPT only, ZUPT + height update, the 21-state filter and the 9-state filter with the Table 1 and the true
    geometry; the 21-state calibration after one trial; and the B12 checks."""
    from estimators.trajectory import TABLE1_GEOMETRY, DuongSuhParams, duong_suh_trajectory
    from estimators.trajectory._sim_ds import simulate_ds_walk
    from estimators.trajectory.evaluation import rms_error_per_axis
    methods = {"zupt_only": (DuongSuhParams(use_ranges=False, estimate_calibration=False), False),
               "zupt_height": (DuongSuhParams(use_ranges=False, estimate_calibration=False,
                                              height_update_var=1e-4), False),
               "ds21": (DuongSuhParams(), False),
               "ds9_table1": (DuongSuhParams(estimate_calibration=False), False),
               "ds9_true": (DuongSuhParams(estimate_calibration=False), True)}
    errs = {m: [] for m in methods}
    cal = []
    for seed in range(seeds):
        w = simulate_ds_walk(seed, pitch_deg=pitch_deg)
        for m, (p, true_geo) in methods.items():
            r = duong_suh_trajectory(w.gyr, w.acc, w.ranges, sampling_rate_hz=w.sampling_rate_hz,
                                     geometry=w.geometry if true_geo else TABLE1_GEOMETRY, params=p,
                                     initial_quat=w.quat0, initial_height_m=None if p.use_ranges else float(w.pos[0, 2]))
            errs[m].append(rms_error_per_axis(r.pos, w.pos))
            if m == "ds21":
                cal.append(r.geometry.as_array())
    mean = {m: np.mean(v, axis=0) for m, v in errs.items()}
    g_true, g0, g_est = w.geometry.as_array(), TABLE1_GEOMETRY.as_array(), np.mean(cal, axis=0)
    ez = {m: float(v[2]) for m, v in mean.items()}
    out = {"seeds": seeds, "pitch_deg": pitch_deg,
           "rms_error_m": {m: {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])} for m, v in mean.items()},
           "calibration": {"r_a_x": [float(g0[0, 0]), float(g_est[0, 0]), float(g_true[0, 0])],
                           "r_b_x": [float(g0[1, 0]), float(g_est[1, 0]), float(g_true[1, 0])],
                           "order": "initial (Table 1), estimated (mean over seeds), truth (eq. 24)",
                           "baseline_m": float(np.linalg.norm(g_est[0] - g_est[1]))},
           "vertical_rms_error_mm": 1000 * ez["ds21"],
           "vertical_improvement_vs_zupt": ez["zupt_only"] / ez["ds21"]}
    out["checks"] = {"ez_le_3mm": ez["ds21"] <= 0.003,
                     "ez_ratio_le_0.35": ez["ds21"] <= 0.35 * ez["zupt_only"],
                     "ez_le_zupt_height": ez["ds21"] <= ez["zupt_height"],
                     "xy_within_25pct": bool(all(abs(mean["ds21"][j] / mean["zupt_only"][j] - 1) <= 0.25 for j in (0, 1))),
                     "cal_x_moves_toward_truth": bool(abs(g_est[0, 0] - g_true[0, 0]) < abs(g0[0, 0] - g_true[0, 0])
                                                      and abs(g_est[1, 0] - g_true[1, 0]) < abs(g0[1, 0] - g_true[1, 0])),
                     "ds9_true_within_20pct_of_ds21": abs(ez["ds9_true"] / ez["ds21"] - 1) <= 0.2}
    return out


@click.command("trajectory")
@click.option("--loop", "loops", multiple=True, type=click.Path(path_type=Path),
              help="loop-walk CSV (repeatable; the foot ends where it started)")
@click.option("--duong-suh", "duong_suh", is_flag=True,
              help="Duong & Suh distance-sensor filters on the simulated walk of spec B11 (B12 targets)")
@click.option("--seeds", default=10, show_default=True, type=click.IntRange(1, 1000), help="seeds for --duong-suh")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(loops: tuple[Path, ...], duong_suh: bool, seeds: int, as_json: bool) -> None:
    """Walked distance and final position error (m) of foot-IMU loop walks, in the order given; and/or the
    Duong & Suh vertical accuracy with and without shoe distance sensors on simulated walking.

    \b
    Examples:
      stridelab bench trajectory --loop walk1.csv --loop walk2.csv --json
      stridelab bench trajectory --duong-suh --json
    """
    if not loops and not duong_suh:
        raise UserError("nothing to do: give --loop FILE (repeatable) and/or --duong-suh")
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
    ds = duong_suh_benchmark(seeds) if duong_suh else None
    if as_json:
        emit_json({"files": rows, **({"duong_suh": ds} if ds else {})} if loops else {"duong_suh": ds})
        return
    for r in rows:
        click.echo(f"{r['file']}: distance {r['distance_m']} m, final position error {r['final_position_error_m']} m")
    if ds:
        for m, e in ds["rms_error_m"].items():
            click.echo(f"{m:12s} E_rms x {e['x'] * 1000:6.1f} mm  y {e['y'] * 1000:6.1f} mm  z {e['z'] * 1000:6.2f} mm")
        click.echo(f"vertical: {ds['vertical_rms_error_mm']:.2f} mm with distance sensors, "
                   f"{ds['vertical_improvement_vs_zupt']:.1f}x better than ZUPT only; checks {ds['checks']}")
