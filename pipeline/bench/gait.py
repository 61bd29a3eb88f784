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
``by_tolerance`` repeats the event figures at ±0.1 s (gaitmap's evaluation convention) and ±0.5 s: a detection
0.4 s off is not a useful contact, so ±0.1 s is the stricter, more honest reading.

Unannotated steps: the reference gives exactly one IC and one TC per hand-labelled stride. When the markers show the
foot standing still (heel *and* toe marker speed < 0.1 m/s for ≥ 0.2 s) between a stride's reference TC and IC, the
foot made an extra step there that the reference does not label (the left foot's pivot in the 180° turn of the example
walk). Detections strictly between that TC and IC that match no reference event are reported as
``{ic,tc}_unannotated`` and not counted as false positives (they cannot be scored either way).
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
EVENT_TOLERANCES_S = (0.1, 0.5)
STRIDE_TOL_S = 0.3
STILL_SPEED_M_S = 0.1      # marker speed below which the foot is still (marker noise is ~0.01-0.03 m/s at 100 Hz)
STILL_MIN_S = 0.2          # shortest still period that counts as a foot placement (shorter than any real stance)


def unannotated_spans(foot, fs: float, mocap_fs: float) -> np.ndarray:
    """(K, 2) IMU-sample spans (ref TC, ref IC) of reference strides whose marker data show the foot standing still
    (heel and toe marker speed < ``STILL_SPEED_M_S`` for ≥ ``STILL_MIN_S``) between TC and IC: an extra,
    unlabelled foot placement (module docstring)."""
    heel, toe = foot.markers["FCC"], foot.markers["TOE"]
    sp = np.maximum(np.linalg.norm(np.gradient(heel, axis=0), axis=1),
                    np.linalg.norm(np.gradient(toe, axis=0), axis=1)) * mocap_fs
    still = np.nan_to_num(sp, nan=np.inf) < STILL_SPEED_M_S
    need = int(round(STILL_MIN_S * mocap_fs))
    out = []
    for tc, ic in foot.strides[:, [3, 2]]:
        a, b = int(np.ceil(tc / fs * mocap_fs)), int(np.floor(ic / fs * mocap_fs))
        run = best = 0
        for v in still[max(a, 0):max(b, 0)]:
            run = run + 1 if v else 0
            best = max(best, run)
        if best >= need:
            out.append((int(tc), int(ic)))
    return np.array(out, np.int64).reshape(-1, 2)


def _event_metrics(det_all, ref, fs, tol_s, lo, hi, spans) -> dict:
    from estimators.gait.evaluation import match_events
    det = det_all[(det_all >= lo) & (det_all <= hi)]
    m = match_events(det, ref, tolerance_samples=int(round(tol_s * fs)))
    fp = m.fp
    unann = np.array([d for d in fp if any(a < d < b for a, b in spans)], np.int64)
    fp = np.array([d for d in fp if d not in set(unann.tolist())], np.int64)
    err_ms = m.error_samples / fs * 1000.0
    tp, nfp, nfn = m.tp, len(fp), len(m.fn)
    nun = len(unann)
    return {"sensitivity": tp / (tp + nfn) if tp + nfn else None, "precision": tp / (tp + nfp) if tp + nfp else None,
            # precision if every unannotated detection were counted as a false positive (the reference's own reading)
            "precision_strict": tp / (tp + nfp + nun) if tp + nfp + nun else None,
            "timing_mae_ms": float(np.abs(err_ms).mean()) if len(err_ms) else None,
            "timing_mean_ms": float(err_ms.mean()) if len(err_ms) else None,
            "tp": tp, "fp": nfp, "fn": nfn, "unannotated": int(len(unann)), "_err": err_ms}


def _foot_metrics(foot, fk, fs, mocap_fs) -> dict:
    from estimators.gait.evaluation import match_strides
    ref = foot.strides
    lo, hi = int(ref[:, 0].min()), int(ref[:, 1].max())
    spans = unannotated_spans(foot, fs, mocap_fs)
    out = {"unannotated_spans": spans.tolist()}
    by_tol = {}
    for tol in EVENT_TOLERANCES_S:
        by_tol[str(tol)] = {}
        for name, det, col in (("ic", fk.events.ic_idx, 2), ("tc", fk.events.tc_idx, 3)):
            em = _event_metrics(det, ref[:, col], fs, tol, lo, hi, spans)
            for k, v in em.items():
                by_tol[str(tol)][f"{name}_{k}"] = v
    for k, v in by_tol[str(EVENT_TOL_S)].items():
        out[k if not k.endswith("__err") else k] = v
    for name in ("ic", "tc"):
        out[f"_{name}_err"] = out.pop(f"{name}__err")
    out["_by_tolerance"] = by_tol
    if fk.events.tc_pitch_min_idx is not None:          # the thesis' plain TC (pitch minimum), before toe-off (T1)
        em = _event_metrics(fk.events.tc_pitch_min_idx, ref[:, 3], fs, EVENT_TOL_S, lo, hi, spans)
        out["tc_pitch_min_timing_mae_ms"], out["tc_pitch_min_timing_mean_ms"] = em["timing_mae_ms"], em["timing_mean_ms"]
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
        by_tolerance = {}
        for tol in EVENT_TOLERANCES_S:
            bt = {side: res[side]["_by_tolerance"][str(tol)] for side in res}
            ov = {}
            for name in ("ic", "tc"):
                tp = sum(bt[s][f"{name}_tp"] for s in bt)
                fp = sum(bt[s][f"{name}_fp"] for s in bt)
                fn = sum(bt[s][f"{name}_fn"] for s in bt)
                err = np.concatenate([bt[s][f"{name}__err"] for s in bt])
                ov[f"{name}_sensitivity"] = tp / (tp + fn) if tp + fn else None
                ov[f"{name}_precision"] = tp / (tp + fp) if tp + fp else None
                un = sum(bt[s][f"{name}_unannotated"] for s in bt)
                ov[f"{name}_precision_strict"] = tp / (tp + fp + un) if tp + fp + un else None
                ov[f"{name}_timing_mae_ms"] = float(np.abs(err).mean()) if len(err) else None
                ov[f"{name}_timing_mean_ms"] = float(err.mean()) if len(err) else None
                ov[f"{name}_unannotated"] = int(sum(bt[s][f"{name}_unannotated"] for s in bt))
            by_tolerance[str(tol)] = {"overall": ov, "per_foot": {
                side: {k: v for k, v in bt[side].items() if not k.endswith("__err")} for side in bt}}
        overall.update(by_tolerance[str(EVENT_TOL_S)]["overall"])
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
            "stride_tolerance_s": STRIDE_TOL_S, **overall, "per_foot": res, "by_tolerance": by_tolerance,
            "session": session,
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
