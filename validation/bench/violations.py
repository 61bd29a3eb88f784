"""``stridelab bench violations``: what each assumption violation of the simulator does to calibration, joint
angles, gait events and daily activity (issue 16 point 7; scenarios in :mod:`stridelab.validation.simulator.violations`).

Per scenario, ``--participants`` simulated lab sessions of the demo study (calibration trial + one walking trial,
default sensor model) are scored with the project's own scorers:

* calibration: helical angle between the estimated and the true sensor-to-segment rotation of the calibration
  trial (``stridelab.estimators.calibration.helical_angle_deg``, thesis Eq. 19), median over thighs and shanks, method
  ``auto`` (hip flexion/extension), on the true sensor orientations (so only calibration is scored);
* joint angles: RMSE of hip/knee/ankle in the walking trial after the quiet-standing offset removal
  (``stridelab.estimators.joints.angle_errors``), true sensor orientations and the calibration of the calibration trial:
  max over joints of the median over participants, sagittal and out of plane;
* gait events: ``foot_kinematics`` on the measured foot signals of the walking trial, IC/TC sensitivity,
  precision and timing MAE within ±0.1 s of the simulated contacts (``stridelab.estimators.gait.evaluation.event_accuracy``),
  stride-length MAE against the true sensor displacement between the detected stride borders;
* activity (``--activity-days N``): the pipeline's default classifier on N simulated 24 h days whose stairs cadence
  and sit/stand heights come from published ranges (``validation/simulator/_chest_day.py``): per-second
  agreement and balanced accuracy over the reference classes (``stridelab.estimators.activity.evaluation.scores``).

Run-to-run figures are deterministic (seeded); the violation magnitudes are scenario choices stated in
``SCENARIOS``, not measurements.
"""
from __future__ import annotations

import warnings
from dataclasses import replace

import click
import numpy as np

from stridelab.pipeline.console import emit_json, err_console, progress

LEGS = ("thigh_left", "thigh_right", "shank_left", "shank_right")
EVENT_TOL_S = 0.1


def _lab_trials(manifest, person, index: int, seed: int, violations):
    from stridelab.validation.simulator import simulate_lab_session
    out = []
    for rec, truth in simulate_lab_session(manifest, person, index, seed=seed, violations=violations):
        out.append({"trial": rec.metadata.get("trial"), "fs": manifest.sampling_rate_hz, "truth": truth,
                    "acc": {p: d.acc for p, d in rec.imu.items()}, "gyr": {p: d.gyr for p, d in rec.imu.items()},
                    "quat": {"true": truth.sensor_quat}})
    return out[0], out[1:]


def _events(walks) -> dict:
    from stridelab.estimators.gait import foot_kinematics
    from stridelab.estimators.gait.evaluation import event_accuracy, paired_errors
    det = {"IC": [], "TC": []}
    ref = {"IC": [], "TC": []}
    est_len, ref_len = [], []
    for w in walks:
        fs = w["fs"]
        for side in ("left", "right"):
            p = f"foot_{side}"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fk = foot_kinematics(w["gyr"][p], w["acc"][p], sampling_rate_hz=fs)
            det["IC"].append(fk.events.ic_idx / fs)
            det["TC"].append(fk.events.tc_idx / fs)
            ref["IC"].append(np.asarray(w["truth"].events[side]["IC"], float))
            ref["TC"].append(np.asarray(w["truth"].events[side]["TC"], float))
            if len(fk.strides):
                a, b = fk.strides.column("start"), fk.strides.column("end")
                pos = w["truth"].sensor_pos[p]
                est_len.append(fk.strides.column("stride_length_m"))
                ref_len.append(np.hypot(*(pos[b, :2] - pos[a, :2]).T))
    out = {}
    for typ in ("IC", "TC"):
        acc = event_accuracy(det[typ], ref[typ], tolerance_s=EVENT_TOL_S)
        k = typ.lower()
        out.update({f"{k}_sensitivity": acc.sensitivity, f"{k}_precision": acc.precision,
                    f"{k}_timing_mae_ms": acc.timing_mae_ms})
    e = paired_errors(np.concatenate(est_len), np.concatenate(ref_len)) if est_len else {"mae": None, "n": 0}
    out["stride_length_mae_m"], out["strides"] = e["mae"], e["n"]
    return out


def lab_scenario(violations, participants: int, seed: int = 0) -> dict:
    """Calibration, joint-angle and gait-event figures of one scenario (module docstring)."""
    from stridelab.estimators.calibration import helical_angle_deg
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.bench.calibration import _sim_calibrate, _sim_joint_rmse, _true_r_sensor_af
    from stridelab.validation.simulator import study_participants
    m = load_manifest(DEFAULT_MANIFEST)
    m = replace(m, lab=replace(m.lab, walking_trials=1, distance_sensors=False, optical_reference=False))
    cal_err, rmse, qc, walks_all = [], [], [], []
    for i, person in enumerate(study_participants(m, participants, seed)):
        cal_tr, walks = _lab_trials(m, person, i, seed, violations)
        r_true = _true_r_sensor_af(cal_tr["truth"])
        cal = _sim_calibrate(cal_tr, "auto", cal_tr["quat"]["true"])
        cal_err += [float(helical_angle_deg(r_true[p], cal.imus[p].R_sensor_af)) for p in LEGS]
        qc += [cal.imus[p].status for p in LEGS]
        rmse.append(_sim_joint_rmse(walks, cal, "true"))
        walks_all += walks
    keys = sorted(rmse[0])
    med = {k: np.nanmedian(np.stack([r[k] for r in rmse]), axis=0) for k in keys}
    return {"calibration_error_deg_median": float(np.nanmedian(cal_err)),
            "calibration_error_deg_max": float(np.nanmax(cal_err)),
            "calibration_qc": {s: qc.count(s) for s in ("pass", "warn", "fail")},
            "joint_rmse_sagittal_deg_max": float(max(v[0] for v in med.values())),
            "joint_rmse_out_of_plane_deg_max": float(max(max(v[1], v[2]) for v in med.values())),
            "joint_rmse_deg_median": {k: [float(x) for x in v] for k, v in med.items()},
            **_events(walks_all)}


def activity_scenario(n: int) -> dict:
    from stridelab.estimators.activity.evaluation import scores
    from stridelab.validation.bench.activity import simulated_days
    r = simulated_days(n)
    C = np.sum([np.asarray(v["confusion"]) for v in r["per_participant"].values()], axis=0)
    s = scores(C)
    rec = {c: (float(C[i, i] / C[i].sum()) if C[i].sum() else None) for i, c in enumerate(r["classes"])}
    return {"days": n, "agreement_min": r["min_agreement"], "balanced_accuracy": s["balanced_accuracy"],
            "recall_by_class": rec, "max_abs_steps_error_pct": r["max_abs_steps_error_pct"],
            "day": "stairs cadence and sit/stand heights from published ranges (validation/simulator/_chest_day.py)"}


@click.command("violations")
@click.option("--participants", "-n", type=click.IntRange(1, 50), default=3, show_default=True,
              help="Simulated lab sessions per scenario.")
@click.option("--scenario", "only", multiple=True, help="Run only these scenarios (repeatable; default: all).")
@click.option("--activity-days", type=click.IntRange(0, 20), default=2, show_default=True,
              help="Simulated 24 h chest days for the activity row (0 = skip).")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--json", "as_json", is_flag=True, help="Print the table as JSON on stdout.")
def command(participants, only, activity_days, seed, as_json) -> None:
    """What each violation of the methods' assumptions does to calibration, joint angles, events and activity.

    \b
    Examples:
      stridelab bench violations --json
      stridelab bench violations -n 1 --scenario baseline --scenario strap_slip --activity-days 0
    """
    from stridelab.validation.simulator import SCENARIOS
    names = list(only) or list(SCENARIOS)
    bad = [n for n in names if n not in SCENARIOS]
    if bad:
        from stridelab.pipeline.console import UserError
        raise UserError(f"unknown scenario {bad[0]!r}; choose from {', '.join(SCENARIOS)}")
    out = {"participants": participants, "seed": seed, "event_tolerance_s": EVENT_TOL_S, "scenarios": {}}
    with progress(not as_json or err_console.is_terminal) as pb:
        task = pb.add_task("violations", total=len(names) + (1 if activity_days else 0))
        for name in names:
            v, what = SCENARIOS[name]
            pb.update(task, description=f"scenario {name}")
            out["scenarios"][name] = {"what": what, "violations": {k: getattr(v, k) for k in v.__dataclass_fields__},
                                      **lab_scenario(v, participants, seed)}
            pb.advance(task)
        if activity_days:
            pb.update(task, description="activity days")
            out["activity"] = activity_scenario(activity_days)
            pb.advance(task)
    if as_json:
        emit_json(out)
        return
    cols = ("calibration_error_deg_median", "joint_rmse_sagittal_deg_max", "joint_rmse_out_of_plane_deg_max",
            "ic_sensitivity", "ic_timing_mae_ms", "tc_sensitivity", "stride_length_mae_m")
    click.echo("scenario".ljust(24) + "".join(c[:14].rjust(16) for c in cols))
    for name, r in out["scenarios"].items():
        click.echo(name.ljust(24) + "".join(f"{r[c]:16.3f}" if r[c] is not None else " " * 15 + "-" for c in cols))
    if "activity" in out:
        a = out["activity"]
        click.echo(f"activity ({a['days']} days): balanced accuracy {a['balanced_accuracy']:.3f}, "
                   f"min agreement {a['agreement_min']:.3f}")
