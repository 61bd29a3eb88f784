"""``stridelab bench gait``: events, stride length and speed of the foot kinematics on the gaitmap example walk.

Reference (data README): per stride of ``stride_events_sample.csv`` the mocap-derived ``ic`` and ``tc`` (IMU
samples) and the stride borders ``start``/``end`` (mid-stance, ``min_vel``). Reference stride length = horizontal
displacement of the heel marker (FCC) between the stride borders — the same quantity gaitmap ships as the stride
trajectory (``position_sample.csv`` equals the FCC marker path per stride to < 0.1 mm, checked). The foot is flat
and still at both borders, so any point of the foot (the IMU too) moves by the same amount up to foot yaw × lever.

Detected strides (``estimators.gait.foot_kinematics``: own ZUPT stance detection, own IC/TC) are matched to the
reference strides when both borders agree within 0.3 s; events are matched one-to-one within ±0.5 s (thesis
§3.5), counting only detections inside the span the reference annotates ([first start, last end] per foot; the
reference has no events outside its strides). Timing error = detected − reference (positive = late).
Speed: ``foot_kinematics`` of both feet on 10 minutes of 100 Hz data (the example walk resampled and tiled), after a
warm-up call (numba JIT), feet in two threads (the kernels release the GIL).
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import click
import numpy as np

from pipeline.console import UserError, emit_json, err_console, progress

PROJECT_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_GAITMAP = PROJECT_ROOT.parent / "shared" / "data" / "gaitmap_example"
EVENT_TOL_S = 0.5
STRIDE_TOL_S = 0.3


def _foot_metrics(foot, fk, fs, mocap_fs) -> dict:
    from estimators.gait.evaluation import match_events, match_strides
    ref = foot.strides
    lo, hi = int(ref[:, 0].min()), int(ref[:, 1].max())
    out = {}
    for name, det, col in (("ic", fk.events.ic_idx, 2), ("tc", fk.events.tc_idx, 3)):
        det = det[(det >= lo) & (det <= hi)]
        m = match_events(det, ref[:, col], tolerance_samples=int(round(EVENT_TOL_S * fs)))
        err_ms = m.error_samples / fs * 1000.0
        out[f"{name}_sensitivity"] = m.sensitivity
        out[f"{name}_precision"] = m.precision
        out[f"{name}_timing_mae_ms"] = float(np.abs(err_ms).mean()) if len(err_ms) else None
        out[f"{name}_timing_mean_ms"] = float(err_ms.mean()) if len(err_ms) else None
        out[f"{name}_tp"], out[f"{name}_fp"], out[f"{name}_fn"] = m.tp, len(m.fp), len(m.fn)
        out[f"_{name}_err"] = err_ms
    heel = foot.markers["FCC"]
    mi = lambda i: int(round(i / fs * mocap_fs))  # noqa: E731 - IMU sample -> mocap sample (both start together)
    ref_len = np.array([np.hypot(*(heel[mi(e), :2] - heel[mi(s), :2])) for s, e in ref[:, :2]])
    sm = match_strides(fk.strides.idx[:, :2], ref[:, :2], tolerance_samples=int(round(STRIDE_TOL_S * fs)))
    e = sm.errors(fk.strides.column("stride_length_m"), ref_len)
    out["stride_length_mae_m"] = float(np.abs(e).mean()) if len(e) else None
    out["stride_length_mean_error_m"] = float(e.mean()) if len(e) else None
    out["strides_reference"], out["strides_detected"], out["strides_matched"] = len(ref), len(fk.strides), len(e)
    out["_sl_err"] = e
    out["status"] = fk.status
    return out


def speed_2feet_10min(ex, *, threads: int = 2) -> float:
    """Seconds for ``foot_kinematics`` of two feet × 10 min at 100 Hz (example walk resampled to 100 Hz, tiled)."""
    from estimators.gait import foot_kinematics
    fs_in, fs = ex.sampling_rate_hz, 100.0
    n10 = int(600 * fs)
    feet = []
    for foot in (ex.left, ex.right):
        t_in = np.arange(len(foot.gyr)) / fs_in
        t = np.arange(int(t_in[-1] * fs)) / fs
        g = np.column_stack([np.interp(t, t_in, foot.gyr[:, i]) for i in range(3)])
        a = np.column_stack([np.interp(t, t_in, foot.acc[:, i]) for i in range(3)])
        reps = n10 // len(g) + 1
        feet.append((np.tile(g, (reps, 1))[:n10], np.tile(a, (reps, 1))[:n10]))
    foot_kinematics(feet[0][0][:3000], feet[0][1][:3000], sampling_rate_hz=fs)     # warm-up / JIT
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=threads) as pool:
        list(pool.map(lambda ga: foot_kinematics(ga[0], ga[1], sampling_rate_hz=fs), feet))
    return time.perf_counter() - t0


def run_benchmark(directory: Path, *, show_progress: bool = True, speed: bool = True) -> dict:
    """Run the benchmark; returns the JSON-able result (see module docstring)."""
    from estimators.gait import foot_kinematics, gait_session
    from pipeline.formats.gaitmap import load_gaitmap_example
    try:
        ex = load_gaitmap_example(directory)
    except ValueError as e:
        raise UserError(str(e)) from e
    fs = ex.sampling_rate_hz
    res, fks = {}, {}
    with progress(show_progress) as p:
        task = p.add_task("gait", total=3 if speed else 2)
        for foot in (ex.left, ex.right):
            p.update(task, description=f"foot kinematics: {foot.side}")
            fk = foot_kinematics(foot.gyr, foot.acc, sampling_rate_hz=fs)
            fks[foot.side] = fk
            res[foot.side] = _foot_metrics(foot, fk, fs, ex.mocap_rate_hz)
            p.advance(task)
        overall = {}
        for name in ("ic", "tc"):
            tp = sum(res[s][f"{name}_tp"] for s in res)
            fp = sum(res[s][f"{name}_fp"] for s in res)
            fn = sum(res[s][f"{name}_fn"] for s in res)
            err = np.concatenate([res[s][f"_{name}_err"] for s in res])
            overall[f"{name}_sensitivity"] = tp / (tp + fn) if tp + fn else None
            overall[f"{name}_precision"] = tp / (tp + fp) if tp + fp else None
            overall[f"{name}_timing_mae_ms"] = float(np.abs(err).mean()) if len(err) else None
            overall[f"{name}_timing_mean_ms"] = float(err.mean()) if len(err) else None
        sl = np.concatenate([res[s]["_sl_err"] for s in res])
        overall["stride_length_mae_m"] = float(np.abs(sl).mean()) if len(sl) else None
        overall["stride_length_mean_error_m"] = float(sl.mean()) if len(sl) else None
        overall["strides_matched"] = int(len(sl))
        if speed:
            p.update(task, description="speed: 2 feet x 10 min at 100 Hz")
            overall["seconds_2feet_10min"] = speed_2feet_10min(ex)
            p.advance(task)
    for s in res:
        for k in [k for k in res[s] if k.startswith("_")]:
            del res[s][k]
    sess = gait_session(fks["left"], fks["right"])
    session = {"cadence_steps_min": sess.cadence_steps_min, "gait_speed_m_s": sess.gait_speed_m_s,
               "stride_length_m": sess.stride_length_m, "double_support_pct": sess.double_support_pct,
               "symmetry_index_pct": sess.symmetry_index_pct}
    return {"dataset": str(directory), "sampling_rate_hz": fs, "event_tolerance_s": EVENT_TOL_S,
            "stride_tolerance_s": STRIDE_TOL_S, **overall, "per_foot": res, "session": session,
            "reference_gaitmap_rtskalman_rampp": {"stride_length_mae_m": 0.0397, "ic_timing_mean_ms": 48.0,
                                                   "tc_timing_mean_ms": 16.0}}


def simulator_scan(participants: int = 4, acc_noise_rel=(0.0, 0.1, 0.3, 1.0)) -> dict:
    """Stride-length MAE of ``foot_kinematics`` on the platform simulator (``studies.simulator``, walking trials of
    ``participants`` participants) for several c_a (``EskfParams.acc_noise_rel``): parameters chosen on data that is not
    the evaluation walk. Truth = horizontal displacement of the simulated sensor between the detected mid-stances."""
    import warnings
    from dataclasses import replace

    from estimators.gait import FootParams, foot_kinematics
    from estimators.gait.evaluation import paired_errors
    from estimators.trajectory import EskfParams
    from studies.manifest import DEFAULT_MANIFEST, load_manifest
    from studies.simulator import simulate_lab_session, study_participants
    m = load_manifest(DEFAULT_MANIFEST)
    m = replace(m, lab=replace(m.lab, walking_trials=2, distance_sensors=False, optical_reference=False))
    feet = []
    for i, part in enumerate(study_participants(m, participants)):
        for rec, truth in list(simulate_lab_session(m, part, i))[1:]:
            feet += [(rec.imu[p].gyr, rec.imu[p].acc, truth.sensor_pos[p]) for p in ("foot_left", "foot_right")]
    out = {}
    for ca in acc_noise_rel:
        fp = FootParams(trajectory=EskfParams(acc_noise_rel=ca))
        est, ref = [], []
        for gyr, acc, pos in feet:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fk = foot_kinematics(gyr, acc, sampling_rate_hz=m.sampling_rate_hz, params=fp)
            a, b = fk.strides.column("start"), fk.strides.column("end")
            est.append(fk.strides.column("stride_length_m"))
            ref.append(np.hypot(*(pos[b, :2] - pos[a, :2]).T))
        e = paired_errors(np.concatenate(est), np.concatenate(ref))
        out[str(ca)] = {"stride_length_mae_m": e["mae"], "stride_length_mean_error_m": e["mean"], "strides": e["n"]}
    return {"participants": participants, "foot_trials": len(feet), "by_acc_noise_rel": out}


@click.command("gait")
@click.option("--gaitmap", "gaitmap", type=click.Path(path_type=Path), default=DEFAULT_GAITMAP, show_default=True,
              help="folder of the gaitmap example walk (imu_sample.csv, mocap_sample.csv, stride_events_sample.csv)")
@click.option("--no-speed", is_flag=True, help="skip the 2 feet x 10 min speed measurement")
@click.option("--simulator-scan", is_flag=True,
              help="also scan c_a (acceleration-proportional noise) on the platform simulator (not the evaluation walk)")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(gaitmap: Path, no_speed: bool, simulator_scan: bool, as_json: bool) -> None:
    """Gait events (IC/TC sensitivity, precision, timing) and stride length vs the gaitmap mocap reference.

    \b
    Examples:
      stridelab bench gait
      stridelab bench gait --gaitmap ../shared/data/gaitmap_example --json
      stridelab bench gait --no-speed --simulator-scan --json
    """
    if not gaitmap.is_dir():
        raise UserError(f"gaitmap example not found at {gaitmap}; pass --gaitmap DIR (see DESIGN.md 'Real data')")
    result = run_benchmark(gaitmap, show_progress=not as_json or err_console.is_terminal, speed=not no_speed)
    if simulator_scan:
        result["simulator_scan"] = globals()["simulator_scan"]()
    if as_json:
        emit_json(result)
        return
    for k in ("stride_length_mae_m", "ic_sensitivity", "ic_precision", "ic_timing_mae_ms", "tc_sensitivity",
              "tc_precision", "tc_timing_mae_ms", "seconds_2feet_10min"):
        if k in result:
            click.echo(f"{k:>24}: {result[k]}")
