"""Hemiparetic gait bench (issue 18): strides, events and stride length of ``stridelab.estimators.gait.foot_kinematics`` on
the simulated stroke walks of ``stridelab.validation.simulator.hemiparetic_gait`` (mild / moderate / severe).

Reference strides = the simulator's swings (its own TC and IC, footprint k → k+1). A detected stride (a row of the
``StrideTable``) matches a reference stride when its TC and its IC both lie within ``TOL_S`` of the reference's
(``stridelab.estimators.gait.evaluation.match_strides`` on the (TC, IC) pairs, one-to-one): stride sensitivity = matched /
reference strides, precision = matched / detected strides. Events: ``event_accuracy`` (±``TOL_S``, one-to-one);
timing error = detected − true contact (positive = late), MAE over IC and TC. Stride length: ``paired_errors`` of
the detected length against the horizontal displacement of the sensor between the two true footprints of the
matched reference stride.

``TOL_S`` = 0.2 s, chosen a priori: less than half the shortest simulated swing (0.4 s), so a detection can never
match the neighbouring event of the same type, and wider than any timing error a clinician could still use.
Subjects: ``hemiparetic_subjects("bench")`` (reported per severity; looked at while changing the detector) and
``"heldout"`` (other subjects, scored only for the report, ``heldout``); ``"dev"`` subjects were used to diagnose.
"""
from __future__ import annotations

import warnings

import numpy as np

TOL_S = 0.2
STRIDES_PER_TRIAL = 20
SUMMARY_KEYS = ("paretic_stride_sensitivity", "paretic_stride_precision", "other_stride_sensitivity",
                "other_stride_precision", "event_timing_mae_ms", "stride_length_mae_m")


def _foot_records(trial, params=None):
    from stridelab.estimators.gait import FootParams, foot_kinematics
    out = []
    for side, f in trial.feet.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fk = foot_kinematics(f.gyr, f.acc, sampling_rate_hz=trial.rate_hz, params=params or FootParams())
        out.append((f, fk))
    return out


def _score(records, _unused=None) -> dict:
    """Pooled scores of a list of (SimFoot, FootKinematics, rate_hz) of one side class."""
    from stridelab.estimators.gait.evaluation import event_accuracy, match_strides, paired_errors
    n_ref = n_det = n_match = 0
    sl_est, sl_ref = [], []
    ev = {"IC": ([], []), "TC": ([], [])}
    for f, fk, fs in records:
        ref = np.column_stack([np.rint(f.tc_s * fs), np.rint(f.ic_s * fs)]).astype(np.int64)
        det = fk.strides.idx[:, 2:4]
        sm = match_strides(det, ref, tolerance_samples=int(round(TOL_S * fs)))
        n_ref, n_det, n_match = n_ref + len(ref), n_det + len(det), n_match + len(sm.det_rows)
        true_len = np.hypot(*(f.footprints[1:, :2] - f.footprints[:-1, :2]).T)
        sl_est.append(fk.strides.column("stride_length_m")[sm.det_rows])
        sl_ref.append(true_len[sm.ref_rows])
        ev["IC"][0].append(fk.events.ic_idx / fs)
        ev["IC"][1].append(f.ic_s)
        ev["TC"][0].append(fk.events.tc_idx / fs)
        ev["TC"][1].append(f.tc_s)
    out = {"strides_reference": n_ref, "strides_detected": n_det, "strides_matched": n_match,
           "stride_sensitivity": n_match / n_ref if n_ref else None,
           "stride_precision": n_match / n_det if n_det else None}
    errs = []
    for typ, (d, r) in ev.items():
        a = event_accuracy(d, r, tolerance_s=TOL_S)
        out[f"{typ.lower()}_sensitivity"], out[f"{typ.lower()}_precision"] = a.sensitivity, a.precision
        out[f"{typ.lower()}_timing_mae_ms"], out[f"{typ.lower()}_timing_mean_ms"] = a.timing_mae_ms, a.timing_mean_ms
        errs.append((a.pairs_s[:, 0] - a.pairs_s[:, 1]) * 1000.0)
    e = np.concatenate(errs)
    out["event_timing_mae_ms"] = float(np.abs(e).mean()) if len(e) else None
    pe = paired_errors(np.concatenate(sl_est), np.concatenate(sl_ref))
    out["stride_length_mae_m"], out["stride_length_mean_error_m"] = pe["mae"], pe["mean"]
    return out


def _finite(x):
    """JSON-safe: NaN / inf (a class without matched strides or events) -> None, recursively."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    return x


def _summary(par: dict, oth: dict, recs_all) -> dict:
    both = _score(recs_all, None)
    return {"paretic_stride_sensitivity": par["stride_sensitivity"], "paretic_stride_precision": par["stride_precision"],
            "other_stride_sensitivity": oth["stride_sensitivity"], "other_stride_precision": oth["stride_precision"],
            "event_timing_mae_ms": both["event_timing_mae_ms"], "stride_length_mae_m": both["stride_length_mae_m"]}


def hemiparetic_benchmark(*, split: str = "bench", params=None, strides: int = STRIDES_PER_TRIAL,
                          rate_hz: float = 100.0, show_progress: bool = False) -> dict:
    """Per severity and side class (paretic / other) and the pooled ``summary`` (module docstring)."""
    from stridelab.validation.simulator.hemiparetic_gait import SEVERITIES, hemiparetic_subjects, simulate_hemiparetic_trial
    by_sev = {s: {"paretic": [], "other": []} for s in SEVERITIES}
    for sev, subj in hemiparetic_subjects(split):
        tr = simulate_hemiparetic_trial(sev, subj, strides=strides, rate_hz=rate_hz)
        for f, fk in _foot_records(tr, params):
            by_sev[sev]["paretic" if f.paretic else "other"].append((f, fk, tr.rate_hz))
    out = {"tolerance_s": TOL_S, "rate_hz": rate_hz, "split": split,
           "subjects": {s: sorted({n for v, n in hemiparetic_subjects(split) if v == s}) for s in SEVERITIES},
           "by_severity": {}}
    allp, allo = [], []
    for sev, d in by_sev.items():
        p, o = _score(d["paretic"], None), _score(d["other"], None)
        out["by_severity"][sev] = {"paretic": p, "other": o, "summary": _summary(p, o, d["paretic"] + d["other"])}
        allp += d["paretic"]
        allo += d["other"]
    out["summary"] = _summary(_score(allp, None), _score(allo, None), allp + allo)
    return _finite(out)


def hemiparetic_report(*, before: bool = False) -> dict:
    """The ``hemiparetic`` key of ``stridelab bench gait``: bench subjects per severity and pooled (``summary``),
    ``heldout`` (subjects 200–203 of each severity) and, with ``before``, both with the swing rules off."""
    from dataclasses import replace

    from stridelab.estimators.gait import FootParams
    out = hemiparetic_benchmark(split="bench")
    out["heldout"] = hemiparetic_benchmark(split="heldout")
    if before:
        off = replace(FootParams(), swing_events=False)
        out["before_swing_events_off"] = {"bench": hemiparetic_benchmark(split="bench", params=off),
                                          "heldout": hemiparetic_benchmark(split="heldout", params=off)}
    return out
