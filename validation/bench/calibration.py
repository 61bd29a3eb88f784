"""``stridelab bench calibration``: sensor-to-segment calibration and joint-angle accuracy and speed.

Scenes with known mounting misalignment: the platform study simulator (``stridelab.validation.simulator``, lab
sessions with a calibration trial and walking trials, when available) or the built-in kinematic
fixture of :mod:`stridelab.validation.simulator.lower_body` (``--scene synthetic``). Figures:

* calibration error = helical angle between estimated and true sensor-to-segment rotation (thesis
  Eq. 19), median per segment over participants, for hip flexion/extension and straight walking;
* joint-angle RMSE against the simulated truth after quiet-standing offset removal (orientation
  from the truth, so only calibration error is scored, as thesis Eq. 20-21), sagittal and out of plane;
  on the simulator scene also with the default offline orientation estimator on the noisy signals;
* simulator scene: calibration error against the true frame tilted upright in quiet standing (a
  diagnostic: how much of the error the standing posture explains; the simulated standing is
  upright within about 1°, so both figures nearly agree);
* error against the number of hip FE repetitions (k = 1 … 20) and the share of participants with
  |θ_{k+1} − θ_k| < 0.5° (thesis: ≥ 10 repetitions suffice);
* seconds for calibration + joint angles + gait curves of a 7-IMU, 10-minute session after orientation.
"""
from __future__ import annotations

import time

import click
import numpy as np

from stridelab.pipeline.console import UserError, emit_json, err_console, progress

SEGMENTS = ("pelvis", "thigh", "shank", "foot")
PLANE = {0: "sagittal", 1: "frontal", 2: "transverse"}


def _seg(p: str) -> str:
    return p.split("_")[0]


def _synthetic_participant(rng, reps: int, posture_sd_deg: float, crosstalk: float):
    from stridelab.validation.simulator.lower_body import calibration_trial, random_mounts, walking_trial
    mounts = random_mounts(rng)
    cal = calibration_trial(mounts=mounts, rng=rng, fe_reps=reps, standing_offsets=posture_sd_deg, crosstalk=crosstalk)
    walk = walking_trial(mounts=mounts, rng=rng, strides=20, noise=True, crosstalk=crosstalk)
    return mounts, cal, walk


def _calibration_errors(tr, mounts, method: str) -> tuple[dict, object]:
    from stridelab.estimators.calibration import CalibrationParams, calibrate_session, helical_angle_deg
    cal = calibrate_session(tr.acc, tr.gyr, sampling_rate_hz=tr.sampling_rate_hz, windows=None,
                            params=CalibrationParams(method=method), quats=tr.quat_sensor)
    return {p: float(helical_angle_deg(mounts[p], c.R_sensor_af)) for p, c in cal.imus.items()}, cal


def _joint_rmse(walk, cal) -> dict:
    from stridelab.estimators.joints import angle_errors, compute_joint_angles, remove_standing_offset
    ja = compute_joint_angles(walk.quat_sensor, cal, standing=walk.standing)
    out = {}
    w0, w1 = walk.windows.walking
    mask = np.zeros(len(next(iter(walk.quat_sensor.values()))), bool)
    mask[w0:w1] = True
    for key, est in ja.angles_deg.items():
        ref, _ = remove_standing_offset(walk.angles_deg[key], walk.standing)
        out[key] = angle_errors(ref, est, mask=mask).rmse_deg
    return out


def _reps_curve(tr, mounts, k_max: int) -> dict:
    """θ (deg) per leg segment for the first k hip FE repetitions of each leg, k = 1..k_max."""
    from stridelab.estimators.calibration import CalibrationParams, CalibrationWindows, calibrate_session, helical_angle_deg
    fs = tr.sampling_rate_hz
    period = 2.0 * fs
    out = {}
    for k in range(1, k_max + 1):
        fe = {s: (a, int(a + k * period)) for s, (a, b) in tr.windows.hip_fe.items()}
        w = CalibrationWindows(standing=tr.windows.standing, hip_fe=fe, walking=None, source="manual")
        cal = calibrate_session(tr.acc, tr.gyr, sampling_rate_hz=fs, windows=w,
                                params=CalibrationParams(method="hip_fe", min_fe_repetitions=1),
                                placements=("thigh_left", "thigh_right", "shank_left", "shank_right",
                                            "foot_left", "foot_right"))
        out[k] = {p: float(helical_angle_deg(mounts[p], c.R_sensor_af)) for p, c in cal.imus.items()}
    return out


def _speed(rng, minutes: float, repeats: int = 3) -> dict:
    from stridelab.estimators.calibration import calibrate_session
    from stridelab.validation.simulator.lower_body import calibration_trial, random_mounts, walking_trial
    from stridelab.estimators.joints import compute_joint_angles, session_gait_curves
    mounts = random_mounts(rng)
    cal_tr = calibration_trial(mounts=mounts, rng=rng)
    strides = int(minutes * 60 / 1.1)
    walk = walking_trial(mounts=mounts, rng=rng, strides=strides, standing_s=3.0)
    n = len(walk.quat_sensor["pelvis"])
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        cal = calibrate_session(cal_tr.acc, cal_tr.gyr, sampling_rate_hz=100.0, quats=cal_tr.quat_sensor)
        ja = compute_joint_angles(walk.quat_sensor, cal, standing=walk.standing)
        session_gait_curves(ja, walk.ic, sampling_rate_hz=100.0)
        best = min(best, time.perf_counter() - t0)
    return {"imus": 7, "samples_per_imu": n, "minutes": n / 100.0 / 60.0, "seconds": best,
            "goal_s": 1.0, "pass": bool(best < 1.0)}


# ---- the platform simulator scene ----------------------------------------------------------------

def _true_r_sensor_af(truth) -> dict:
    """placement -> true R_sensor_af: the simulator's q_sensor = q_segment ⊗ q_mount, so R_sensor_af = R_mountᵀ.

    The simulator's segment frame is the ISB anatomical frame (y from the distal to the proximal
    joint centre, x anterior, z right), the frame the thesis reference calibration (Eq. 18) uses, so
    this is the truth of Eq. 19. The thesis method reaches it when the segment's y axis is vertical
    in quiet standing, which the simulated standing is (within about 1°, plus sway)."""
    from stridelab.estimators.quaternion import quat_to_matrix
    return {p: quat_to_matrix(np.asarray(q, float)).T for p, q in truth.mounting_quat.items()}


def _upright_r_sensor_af(truth, r_true: dict, standing: tuple[int, int]) -> dict:
    """The true rotation re-referenced to the segment frame tilted so that its y axis is vertical in
    quiet standing: what a standing-vertical method (thesis Eq. 14) can reach when the simulated
    standing posture has the knee slightly flexed (thigh and shank y axes not vertical)."""
    from stridelab.estimators.quaternion import quat_to_matrix
    out = {}
    for p, R in r_true.items():
        Rg = quat_to_matrix(truth.segment_quat[p][standing[0]:standing[1]])
        up = np.einsum("nji,j->i", Rg, [0.0, 0.0, 1.0])
        up /= np.linalg.norm(up)                                   # world vertical in the segment frame
        y = np.array([0.0, 1.0, 0.0])
        v, c = np.cross(y, up), float(y @ up)
        K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        R_af_af2 = np.eye(3) + K + K @ K / (1.0 + c)                 # minimal rotation taking y to up
        out[p] = R @ R_af_af2
    return out


def _sim_participant(manifest, participant, index: int, seed: int, estimate):
    """Calibration trial, walking trials and their truths of one simulated lab session, with the
    sensor orientations of the default orientation estimator beside the true ones."""
    from stridelab.validation.simulator import simulate_lab_session
    trials = []
    for rec, truth in simulate_lab_session(manifest, participant, index, seed=seed):
        acc = {p: d.acc for p, d in rec.imu.items()}
        gyr = {p: d.gyr for p, d in rec.imu.items()}
        fs = manifest.sampling_rate_hz
        q_est = {p: estimate(d.gyr, d.acc, d.mag, sampling_rate_hz=fs).quat for p, d in rec.imu.items()}
        trials.append({"trial": rec.metadata.get("trial"), "acc": acc, "gyr": gyr, "fs": fs, "truth": truth,
                       "quat": {"true": truth.sensor_quat, "estimated": q_est}})
    return trials[0], trials[1:]


def _sim_calibrate(cal_tr, method: str, quats):
    from stridelab.estimators.calibration import CalibrationParams, calibrate_session
    return calibrate_session(cal_tr["acc"], cal_tr["gyr"], sampling_rate_hz=cal_tr["fs"],
                             params=CalibrationParams(method=method), quats=quats)


def _sim_joint_rmse(walks, cal, source: str) -> dict:
    """key -> (3,) RMSE (deg) over the walking trials, both sides offset-corrected on the same standing."""
    from stridelab.estimators.calibration import first_quiet_standing
    from stridelab.estimators.joints import angle_errors, compute_joint_angles, remove_standing_offset
    sq = {}
    for w in walks:
        st = first_quiet_standing(w["acc"], w["gyr"], sampling_rate_hz=w["fs"]) or (0, int(w["fs"]))
        ja = compute_joint_angles(w["quat"][source], cal, standing=st)
        for key, est in ja.angles_deg.items():
            ref, _ = remove_standing_offset(w["truth"].joint_angles_deg[key], st)
            e = angle_errors(ref, est).rmse_deg
            sq.setdefault(key, []).append(np.asarray(e) ** 2)
    return {k: np.sqrt(np.mean(v, axis=0)) for k, v in sq.items()}


def _sim_reps_curve(cal_tr, r_true: dict, reps: int) -> dict:
    """θ (deg) of thighs and shanks from the first k of the ``reps`` simulated hip FE repetitions (true
    windows), k = 1..reps (the feet do not rotate in the simulated hip FE and are left out)."""
    from stridelab.estimators.calibration import CalibrationParams, CalibrationWindows, calibrate_session, helical_angle_deg
    fs = cal_tr["fs"]
    tw = cal_tr["truth"].windows
    stand = next((int(a * fs), int(b * fs)) for lab, a, b, s in tw if lab == "quiet_standing")
    fe = {s: (a, b) for lab, a, b, s in tw if lab == "hip_flexion_extension"}
    out = {}
    for k in range(1, reps + 1):
        win = {}
        for s, (a, b) in fe.items():
            period = (b - a) / reps                                  # simulator: sin(2π reps (t − t0) / (t1 − t0))
            win[s] = (int(a * fs), int(min(b, a + k * period) * fs))
        w = CalibrationWindows(standing=stand, hip_fe=win, walking=None, source="manual")
        cal = calibrate_session(cal_tr["acc"], cal_tr["gyr"], sampling_rate_hz=fs, windows=w,
                                params=CalibrationParams(method="hip_fe", min_fe_repetitions=1),
                                placements=("thigh_left", "thigh_right", "shank_left", "shank_right"))
        out[k] = {p: float(helical_angle_deg(r_true[p], c.R_sensor_af)) for p, c in cal.imus.items()}
    return out


def _simulator_available() -> bool:
    try:
        import stridelab.validation.simulator  # noqa: F401
    except ImportError:
        return False
    return True


def _median(xs):
    xs = [x for x in xs if np.isfinite(x)]
    return float(np.median(xs)) if xs else float("nan")


@click.command("calibration")
@click.option("--participants", "-n", type=click.IntRange(1, 200), default=6, show_default=True,
              help="Simulated participants (each with its own random mounting misalignment).")
@click.option("--scene", type=click.Choice(["auto", "simulator", "synthetic"]), default="auto", show_default=True,
              help="auto: the platform study simulator (stridelab.validation.simulator, demo manifest) when installed, else the "
                   "built-in kinematic fixture.")
@click.option("--reps", type=click.IntRange(10, 40), default=20, show_default=True,
              help="Hip flexion/extension repetitions per leg in the calibration trial (thesis protocol: 20).")
@click.option("--minutes", type=click.FloatRange(0.5, 120), default=10.0, show_default=True,
              help="Session length for the speed figure.")
@click.option("--posture-sd-deg", type=click.FloatRange(0, 10), default=2.0, show_default=True,
              help="Synthetic scene: SD of the neutral standing joint angles (0 = segments upright in standing).")
@click.option("--crosstalk", type=click.FloatRange(0, 3), default=1.0, show_default=True,
              help="Synthetic scene: scale of the non-sagittal motion in walking and hip FE (0 = single-axis).")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--json", "as_json", is_flag=True, help="Print the figures as JSON on stdout.")
def command(participants, scene, reps, minutes, posture_sd_deg, crosstalk, seed, as_json) -> None:
    """Calibration error per segment (hip FE and walking), joint-angle RMSE, error vs repetitions, speed.

    \b
    Examples:
      stridelab bench calibration --json
      stridelab bench calibration -n 20 --scene synthetic --seed 3
    """
    if scene == "auto":
        scene = "simulator" if _simulator_available() else "synthetic"
    if scene == "simulator" and not _simulator_available():
        raise UserError("the platform simulator (stridelab.validation.simulator) is not installed; use --scene synthetic")
    rng = np.random.default_rng(seed)
    errs = {"hip_fe": [], "walking": []}
    errs_upright = {"hip_fe": [], "walking": []}
    rmse = {"hip_fe": [], "walking": []}
    rmse_est = {"hip_fe": [], "walking": []}
    statuses = {"hip_fe": [], "walking": []}
    curves = []
    with progress(not as_json) as pb:
        task = pb.add_task("simulated participants", total=participants)
        if scene == "simulator":
            from stridelab.estimators.calibration import first_quiet_standing, helical_angle_deg
            from stridelab.estimators.orientation import DEFAULT_OFFLINE, ESTIMATORS
            from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
            from stridelab.validation.simulator import study_participants
            from dataclasses import replace
            m = load_manifest(DEFAULT_MANIFEST)
            m = replace(m, lab=replace(m.lab, hip_repetitions=reps, distance_sensors=False, optical_reference=False))
            for i, person in enumerate(study_participants(m, participants, seed)):
                cal_tr, walks = _sim_participant(m, person, i, seed, ESTIMATORS[DEFAULT_OFFLINE])
                r_true = _true_r_sensor_af(cal_tr["truth"])
                st = first_quiet_standing(cal_tr["acc"], cal_tr["gyr"], sampling_rate_hz=cal_tr["fs"])
                r_up = _upright_r_sensor_af(cal_tr["truth"], r_true, st)
                for method, mp in (("hip_fe", "auto"), ("walking", "walking")):
                    cal = _sim_calibrate(cal_tr, mp, cal_tr["quat"]["true"])
                    errs[method].append({p: float(helical_angle_deg(r_true[p], c.R_sensor_af)) for p, c in cal.imus.items()})
                    errs_upright[method].append({p: float(helical_angle_deg(r_up[p], c.R_sensor_af))
                                                 for p, c in cal.imus.items()})
                    statuses[method].append({p: c.status for p, c in cal.imus.items()})
                    rmse[method].append(_sim_joint_rmse(walks, cal, "true"))
                    cal_e = _sim_calibrate(cal_tr, mp, cal_tr["quat"]["estimated"])
                    rmse_est[method].append(_sim_joint_rmse(walks, cal_e, "estimated"))
                curves.append(_sim_reps_curve(cal_tr, r_true, reps))
                pb.advance(task)
        else:
            for _ in range(participants):
                mounts, cal_tr, walk = _synthetic_participant(rng, reps, posture_sd_deg, crosstalk)
                for method in ("hip_fe", "walking"):
                    e, cal = _calibration_errors(cal_tr, mounts, method)
                    errs[method].append(e)
                    statuses[method].append({p: c.status for p, c in cal.imus.items()})
                    rmse[method].append(_joint_rmse(walk, cal))
                curves.append(_reps_curve(cal_tr, mounts, reps))
                pb.advance(task)

    def calib_table(errs):
        out = {}
        for method, rows in errs.items():
            out[method] = {seg: _median([v for r in rows for p, v in r.items() if _seg(p) == seg]) for seg in SEGMENTS}
            out[method]["max_of_medians"] = max(v for k, v in out[method].items() if k in SEGMENTS)
            out[method]["pass"] = bool(out[method]["max_of_medians"] <= 2.0)
        return out

    def joint_table(rmse):
        joints = {}
        for method, rows in rmse.items():
            per = {}
            for key in rows[0]:
                mm = np.nanmedian(np.stack([r[key] for r in rows]), axis=0)
                per[key] = {PLANE[i]: float(mm[i]) for i in range(3)}
            sag = max(v["sagittal"] for v in per.values())
            oop = max(max(v["frontal"], v["transverse"]) for v in per.values())
            joints[method] = {"median_rmse_deg": per, "max_sagittal_deg": sag, "max_out_of_plane_deg": oop,
                              "pass": bool(sag <= 2.0 and oop <= 4.0)}
        return joints

    calib = calib_table(errs)
    joints = joint_table(rmse)
    qc = {method: {st: sum(v == st for r in rows for v in r.values()) for st in ("pass", "warn", "fail")}
          for method, rows in statuses.items()}
    ks = sorted(curves[0])
    reps_out = {"k": ks}
    leg_segs = ("thigh", "shank") if scene == "simulator" else ("thigh", "shank", "foot")
    for seg in leg_segs:
        # one sample per participant and leg (the thesis: one IMU per segment on one leg per participant)
        th = np.array([[c[k][p] for k in ks] for c in curves for p in sorted(c[ks[0]]) if _seg(p) == seg])
        reps_out[seg] = {"mean_deg": th.mean(axis=0).round(3).tolist(), "sd_deg": th.std(axis=0).round(3).tolist(),
                         "median_deg": np.median(th, axis=0).round(3).tolist(), "n_legs": int(th.shape[0])}
        d = np.abs(np.diff(th, axis=1))                                   # |θ_{k+1} − θ_k| per participant leg
        reps_out[seg]["share_step_below_0p5_deg"] = (d < 0.5).mean(axis=0).round(3).tolist()
    k_ok = [k for i, k in enumerate(ks[:-1])
            if all(reps_out[s]["share_step_below_0p5_deg"][j] >= 0.9 for s in ("thigh", "shank")
                   for j in range(i, len(ks) - 1))]
    reps_out["converged_from_k"] = k_ok[0] if k_ok else None
    reps_out["thesis_finding_reproduced"] = bool(k_ok and k_ok[0] <= 10)
    speed = _speed(np.random.default_rng(seed + 1), minutes)
    result = {"scene": scene, "participants": participants, "seed": seed, "reps": reps,
              "calibration_error_deg": calib, "calibration_qc": qc, "joint_angle_rmse": joints,
              "error_vs_repetitions": reps_out, "speed": speed}
    notes = ["pelvis heading from the thigh axes (spec 7.A7, non-thesis)",
             "speed: arrays of the built-in kinematic fixture (7 IMUs, 100 Hz), calibration + joint angles + "
             "gait curves, orientation not included (issue 5 goal)"]
    if scene == "simulator":
        result["calibration_error_vs_upright_standing_deg"] = calib_table(errs_upright)
        result["joint_angle_rmse_estimated_orientation"] = joint_table(rmse_est)
        result["orientation_estimator"] = DEFAULT_OFFLINE
        notes += ["reference: the simulator's true mounting rotation (R_sensor_af = R_mountᵀ) and true joint angles",
                  "joint_angle_rmse: orientation from the simulated truth (isolates calibration, thesis Eq. 20-21); "
                  "joint_angle_rmse_estimated_orientation: orientation from " + DEFAULT_OFFLINE + " on the noisy "
                  "simulated IMU signals, calibrated with those orientations (what the pipeline does)",
                  "hip_fe = method 'auto': thighs and shanks from the hip flexion/extension; the feet from the "
                  "straight walking, because the simulator keeps the foot level during hip FE (no foot rotation)",
                  "calibration_error_vs_upright_standing_deg: diagnostic, error against the true frame tilted so "
                  "its y axis is vertical in quiet standing; the simulated standing is upright (natural knee "
                  "flexion 0.5-2°, feet under the hips, a few mm of postural sway), so it nearly equals the "
                  "main figure",
                  "walking: the simulator bends the knee in the plane of the walking direction (the feet's 6° "
                  "toe-out is tibial torsion at the ankle), as straight-walking calibration assumes",
                  "error_vs_repetitions: true hip FE windows cut after k repetitions (the simulated repetitions "
                  "vary independently in amplitude, swing plane and coupled rotation; no practice effect is "
                  "simulated); one sample per participant and leg for thighs and shanks; "
                  "thesis_finding_reproduced = spec R-CAL-3 (|θ_k+1 − θ_k| < 0.5° in ≥ 90 % of legs for every "
                  "k from 10 on) — with 12 legs one outlier leg per step is allowed"]
    else:
        result.update(posture_sd_deg=posture_sd_deg, crosstalk=crosstalk)
        notes.insert(0, "orientation taken from the simulated truth (isolates calibration error, thesis Eq. 20-21)")
    result["notes"] = notes
    if as_json:
        emit_json(result)
        return
    for method in ("hip_fe", "walking"):
        c = calib[method]
        err_console.print(f"{method:8s} calibration error median (deg): " +
                          ", ".join(f"{s} {c[s]:.2f}" for s in SEGMENTS) + f"  pass={c['pass']}")
        j = joints[method]
        err_console.print(f"{method:8s} joint RMSE max sagittal {j['max_sagittal_deg']:.2f}°, "
                          f"out of plane {j['max_out_of_plane_deg']:.2f}°  pass={j['pass']}")
    if scene == "simulator":
        for method, j in result["joint_angle_rmse_estimated_orientation"].items():
            err_console.print(f"{method:8s} joint RMSE ({DEFAULT_OFFLINE} orientation) max sagittal "
                              f"{j['max_sagittal_deg']:.2f}°, out of plane {j['max_out_of_plane_deg']:.2f}°  pass={j['pass']}")
        for method, c in result["calibration_error_vs_upright_standing_deg"].items():
            err_console.print(f"{method:8s} calibration error vs upright-standing frame (deg): " +
                              ", ".join(f"{sg} {c[sg]:.2f}" for sg in SEGMENTS))
    err_console.print(f"repetitions: converged from k = {reps_out['converged_from_k']}")
    err_console.print(f"speed: {speed['seconds']:.3f} s for 7 IMUs × {speed['minutes']:.1f} min")
