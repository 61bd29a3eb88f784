"""``stridelab bench trunk-gait``: real-world gait from one trunk sensor against reference initial contacts, walking
bouts, cadence, stride length and walking speed; mobgap (the Mobilise-D reference implementation) as the anchor.

Data. Voisard et al. 2023 (``--voisard``): the L5 sensor of each trial; reference initial contacts = heel strikes of
both feet (foot-IMU algorithms checked by hand) inside ``TrialBoundaries``; one reference walking bout per trial
from its first to its last heel strike, with cadence = 60 (n - 1) / span; its stride length and walking speed from
the two foot MTws (``voisard_foot_reference``: StrideLab's foot INS, strides heel strike to heel strike inside the
trial, mean over both feet; a derived reference, printed as such in ``spatial_references``). Detections are scored inside the trial boundaries ± the matching tolerance (outside them the subject
stands). Mobilise-D standardized data (``--mobilised``): the lower-back SU of every trial; reference = INDIP
``MicroWB`` (initial contacts with side, per-bout cadence, stride length, walking speed); contacts are scored inside
the reference walking bouts ± the tolerance (as Voisard's inside the trial, and as Mobilise-D validated the
contact detectors, within the reference walking: Micó-Amigo et al. 2023), bouts over the whole recording. INDIP's
bouts leave out closing steps and some walking (turns, 110-115 s of Test11) that both tools detect; the figure over
the whole recording, as scored before 2026-12-07, is printed beside as ``mobilised_whole_recording``. Trunk initial
contacts and foot heel strikes are different events: the constant ``ic_offset_s`` maps one to the other and is chosen by cross-validation (below), never on the recording it is scored on.

One scorer: ``stridelab.estimators.trunk_gait.evaluation`` (contacts one-to-one within 0.25 s; bouts one-to-one by IoU ≥ 0.5;
per matched bout the cadence / stride length / speed errors), for StrideLab and mobgap alike.

Blocks. ``shipped_defaults``: TrunkGaitParams() as shipped, no re-tuning. ``cross_validated``: the tuned constants
chosen without the held-out group: leave-one-group-out over the Voisard subjects plus the Mobilise-D participant as
one more group (IC constants: the detector ``ic_method`` — "peak" with ``ic_smooth_s``, ``ic_prominence``,
``ic_fill_prominence``, ``ic_fill_edge_steps``, ``ic_fill_end_steps``, ``ic_turn_prominence``, or "ionescu" with
``ic_zc_sigma_s``, ``ic_zc_min_depth`` (``IC_CANDIDATES``; by default only the "peak" ones, ``IC_CANDIDATES_PEAK``:
the others were never chosen, ``--all-ic-methods`` scores them) — and ``ic_offset_s``, then, given the fold's candidate,
the per-kind offsets ``ic_fill_offset_s`` x ``ic_walk_end_offset_s`` (``GRID_KIND_OFFSETS``) jointly with
``ic_offset_s``, then ``cadence_method``; the block
``shipped_defaults`` names the detector that ships under ``ic_detector``, ``ic_grid_in_sample`` scores every
candidate in-sample); the turn shortening ``sl_turn_per_rad`` (SL_TURN_GRID, at the stride level), then the
stride-length factor ``sl_correction`` jointly with the step-length Hampel filter ``sl_hampel_half_width``, the bout
average ``bout_average`` (mean / median / time-weighted) and the strides averaged ``bout_strides`` (regular / all),
by the same leave-one-group-out against the spatial references (loss = mean over groups of the group's per-bout
stride-length MAE), then the walking-speed definition ``speed_method`` (stride speeds / stride length x cadence) on
the groups' per-bout speed MAE. ``in_sample``: the same grid chosen on everything scored
(marked in-sample). ``anchor``: mobgap's MobilisedPipelineHealthy and ...Impaired on the same recordings, scored by
the same matcher, each as shipped, plus mobgap given the same tuning effort: the pipeline (healthy / impaired), the
input frame (as worn, mapped once per device to mobgap's axes / aligned by our detected frame) and a constant IC
offset chosen by the same leave-one-group-out, then its stride-length factor (``GRID_MOBGAP_SL`` x its shipped
4.587/4) by the same leave-one-group-out as ours. mobgap runs in its own interpreter (``make .venv-mobgap``); when it
is absent the block is ``null`` with the reason.

Loss for the IC constants (per group, pooled over its recordings): the timing cost per reference contact in ms, a
matched contact costing its timing error and a missed or extra one the matching tolerance (250 ms): (Σ|e| + 250 (FN +
FP)) / (TP + FN). (Until 2026-12-07 it was timing MAE + 100 ((1 - sensitivity) + (1 - precision)), which charges a
correct contact found with a timing error above the mean MAE more than a miss: a detector that drops the hard
contacts (closing steps, turns) scored better. With it the leave-one-group-out kept the fill off, see
validation/provenance.toml.)

Speed (``--day``): ``analyse_trunk_gait`` + ``daily_outcomes`` on a 24 h lower-back day at 100 Hz (a Mobilise-D or
Voisard recording inserted every 15 min into still periods with posture changes), CPU seconds of this process.
Progress on stderr, JSON (``--json``) on stdout.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import click
import numpy as np

from stridelab.estimators.trunk_gait._frame import check_units
from stridelab.pipeline.console import UserError, emit_json, err_console

PROJECT_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_VOISARD = PROJECT_ROOT.parent / "shared" / "data" / "voisard_gait"
DEFAULT_MOBGAP_PY = PROJECT_ROOT / ".venv-mobgap" / "bin" / "python"
MOBGAP_RUNNER = PROJECT_ROOT / "validation" / "anchors" / "mobgap_runner.py"
MOBGAP_REQUIREMENTS = PROJECT_ROOT / "validation" / "anchors" / "mobgap-requirements.txt"
KEYS = ("ic_sensitivity", "ic_precision", "ic_timing_mae_ms", "cadence_mape_pct", "stride_length_mae_m",
        "walking_speed_mae_m_s")
# IC detector candidates (each scored with every ic_offset_s of GRID_OFFSET_S): the "peak" detector of _icd over
# ic_smooth_s x ic_prominence x fill (ic_fill_prominence, ic_fill_edge_steps, ic_fill_end_steps) x
# ic_turn_prominence, and the "ionescu"
# detector of _icd_ionescu over ic_zc_sigma_s x ic_zc_min_depth. Dropped after the 2026-12-07 runs (never chosen):
# ic_prominence 0.3, ic_local_window_s 3 s, fill (0.2, 0/1 edge steps).
GRID_SMOOTH_S = (0.11, 0.14)          # 0.08 never chosen (2026-12-07 runs)
GRID_PROMINENCE = (0.7,)               # 0.3 and 0.5 never chosen (2026-12-07 runs)
GRID_FILL = ((0.0, 0, 0), (0.1, 0, 0), (0.1, 1, 0), (0.02, 0, 1), (0.05, 0, 1), (0.1, 0, 1), (0.05, 0, 2))
GRID_TURN_PROMINENCE = (1.0,)         # ic_turn_prominence (1 = off); 0.5 never chosen (2026-12-07 runs, 0/10 folds)
GRID_SUBSAMPLE = (False,)             # ic_subsample: true (parabola vertex) never chosen (0/10 folds, 2026-12-07)
GRID_END_RHYTHM = (False, True)        # ic_fill_end_rhythm (with ic_fill_end_steps > 0)
GRID_ZC_SIGMA_S = (0.12, 0.159, 0.2)
GRID_ZC_DEPTH = (0.0, 0.2, 0.4)
# the Mobilise-D cadence detectors of _icd_cwt (Shin-improved, HKLee-improved) on the acceleration norm (the
# source's input) or the upward acceleration, each as the source (refine 0) and with its contacts timed by the
# upward-acceleration peak within ± ic_refine_s (ic_smooth_s 0.11 s)
# (ic_method, ic_cwt_signal, ic_refine_s, ic_zc_min_depth = their amplitude gate)
GRID_CWT = (("shin", "norm", 0.0, 0.0), ("shin", "norm", 0.15, 0.0), ("hklee", "norm", 0.0, 0.0),
            ("hklee", "norm", 0.1, 0.0), ("hklee", "vertical", 0.1, 0.0), ("hklee", "norm", 0.1, 0.3))
# ic_fill_start_prominence (the first step of every walk, with the fill on): 0 = off, 0.4 SD
GRID_FILL_START = (0.0, 0.4)
# ic_fill_walk_ends (closing steps before every pause inside a sequence, not only at its end; with the closing-step
# fill by the rhythm) and stride_rule ("run" / "consensus": strides IC_i -> IC_{i+2} of <= stride_max_s across a
# stop, as Kluge et al. 2021 / mobgap), both added 2026-12-07 after the per-miss diagnosis of HA-001 (walks of 6-8
# contacts with a 2 s stop dropped by the 4-stride rule); the stride rule only with the fill on
GRID_WALK_ENDS = (False, True)
GRID_STRIDE_RULE = ("run", "consensus")
IC_CANDIDATES_PEAK = tuple(
    {"ic_method": "peak", "ic_smooth_s": s, "ic_prominence": p, "ic_fill_prominence": f[0],
     "ic_fill_edge_steps": f[1], "ic_fill_end_steps": f[2], "ic_fill_start_prominence": fs,
     "ic_turn_prominence": t, "ic_subsample": sub, "ic_fill_end_rhythm": er, "ic_fill_walk_ends": we,
     "stride_rule": sr}
    for s in GRID_SMOOTH_S for p in GRID_PROMINENCE for f in GRID_FILL for fs in GRID_FILL_START
    for t in GRID_TURN_PROMINENCE for sub in GRID_SUBSAMPLE for er in GRID_END_RHYTHM
    for we in GRID_WALK_ENDS for sr in GRID_STRIDE_RULE
    if (f[0] > 0 or fs == 0.0) and (f[2] > 0 or not er) and (er or not we) and (f[0] > 0 or sr == "run"))
# the other detectors: never chosen by any fold nor in-sample in the 2026-12-07 runs (peak in 10/10 folds,
# validation/provenance.toml ic_method), so since 2026-12-08 only scored with ``--all-ic-methods``
IC_CANDIDATES_OTHER = tuple(
    [{"ic_method": "ionescu", "ic_zc_sigma_s": g, "ic_zc_min_depth": d, "ic_refine_s": 0.0}
     for g in GRID_ZC_SIGMA_S for d in GRID_ZC_DEPTH]
    + [{"ic_method": m, "ic_cwt_signal": x, "ic_refine_s": r, "ic_zc_min_depth": d, "ic_smooth_s": 0.11}
       for m, x, r, d in GRID_CWT])
IC_CANDIDATES = IC_CANDIDATES_PEAK + IC_CANDIDATES_OTHER     # the full grid (``--all-ic-methods``)
IC_FIELDS = ("ic_method", "ic_smooth_s", "ic_prominence", "ic_local_window_s", "ic_fill_prominence",
             "ic_fill_edge_steps", "ic_fill_end_steps", "ic_turn_prominence", "ic_zc_sigma_s", "ic_zc_min_depth",
             "ic_fill_start_prominence", "ic_fill_end_rhythm", "ic_subsample", "ic_cwt_signal", "ic_refine_s",
             "ic_fill_walk_ends", "stride_rule", "ic_offset_s", "ic_fill_offset_s", "ic_walk_end_offset_s",
             "cadence_method")
from stridelab.estimators.trunk_gait._pipeline import CADENCE_METHODS  # noqa: E402  chosen after the IC constants
# per-kind offsets (2026-12-08, issue 42 timing): (ic_fill_offset_s, ic_walk_end_offset_s) added to the contacts the
# fill placed and to the last threshold peak before a closing step (``_icd.kind_offsets_s``); chosen after the
# detector candidate, jointly with ic_offset_s, by the same leave-one-group-out on the fold's training groups (only
# for "peak" candidates with the fill on; the others keep (0, 0)). A development run with -0.07 / -0.09 / -0.11 /
# -0.13 x -0.04 / -0.06 / -0.08 found the optimum inside this grid (-0.07 / -0.04 in 10/10 folds)
GRID_KIND_OFFSETS = tuple((fo, we) for fo in (0.0, -0.03, -0.05, -0.07, -0.09) for we in (0.0, -0.02, -0.04, -0.06))
# the jerk minimum lags the heel strike more; the Shin zero crossing leads it by about 0.1 s (up to +0.15 s); 5 ms
# steps: with sub-sample contact times the loss is no longer flat between whole samples
GRID_OFFSET_S = tuple(np.round(np.arange(-0.30, 0.1501, 0.005), 4))
GRID_SL = tuple(np.round(np.arange(0.80, 1.801, 0.01), 3))
GRID_MOBGAP_SL = tuple(np.round(np.arange(0.80, 1.401, 0.01), 3))   # x mobgap's shipped factor 4.587/4
# sl_turn_per_rad, chosen first at the stride level (choose_turn); 0.3, 0.5 and 0.6 added on 2026-12-07 (U-turn
# strides came out at 1.16 x the foot reference with 0.2; 0.4 won 3/10 folds of the 0 / 0.2 / 0.4 grid)
SL_TURN_GRID = (0.0, 0.2, 0.3, 0.4, 0.5, 0.6)
# sl_max_tilt_deg is not in the grid: no Voisard stride leans more than 10.2° (no chair in those trials), so the
# fold that holds out the one Mobilise-D participant cannot choose it (2026-12-07 run with (0, 20, 15, 12, 10, 8):
# off in that fold, 15 in the other 9 and in-sample); ``tilt_gate_check`` prints its in-sample effect
SL_TILT_GATES = (20.0, 15.0, 12.0, 10.0, 8.0)
# (sl_hampel_half_width, bout_average, sl_turn_per_rad, bout_strides, sl_max_tilt_deg)
SL_VARIANTS = tuple((h, a, c, b, 0.0) for h in (0, 1, 2) for a in ("mean", "median", "time") for c in SL_TURN_GRID
                    for b in ("regular", "all"))
SPEED_METHODS = ("stride", "cadence")    # TrunkGaitParams.speed_method, chosen after the stride-length constants
XSENS_TO_MOBGAP = np.diag([1.0, -1.0, -1.0])   # Xsens MTw at L5: x up, z out of the back -> mobgap x up, z forward


@dataclass
class Rec:
    """One recording with its reference (times in s from the first sample)."""
    name: str
    dataset: str            # "voisard" | "mobilised"
    group: str              # CV group (subject / participant)
    trial_group: str        # the trial
    acc: np.ndarray
    gyr: np.ndarray
    fs: float
    height_m: float | None
    leg_length_m: float | None
    ref_ic_s: np.ndarray
    ref_bouts: dict         # start_s, end_s, cadence_spm, stride_length_m, walking_speed_m_s arrays
    window_s: tuple[float, float]
    ic_windows_s: np.ndarray | None = None   # (K, 2) where contacts are scored (± tolerance); None = window_s
    mobgap_axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    sensor_height_m: float | None = None
    foot_reference: dict = field(default_factory=dict)   # Voisard: per-foot mean stride length, stride count
    foot_strides: np.ndarray | None = None   # Voisard: (M, 3) foot-INS strides [start_s, end_s, length_m]
    turn_s: tuple[float, float] | None = None   # Voisard: UTurnBoundaries, s


def _say(msg: str) -> None:
    err_console.print(msg, highlight=False)


def foot_stride_reference(feet: list[tuple[np.ndarray, np.ndarray, np.ndarray]], s0: int, s1: int,
                          fs: float) -> tuple[float, float, int]:
    """(mean stride length m, mean stride speed m/s, number of strides) of the foot strides of one trial.

    ``feet``: per foot (pre_ic, ic, length_m) arrays (sample indices of the heel strikes that begin and end each
    stride, -1 when none began it). A stride counts when it runs from one heel strike to the next of the same foot
    inside the trial [s0, s1] (as INDIP's strides: contact to contact, the first step out of standing is no
    stride); speed = length / (ic - pre_ic). Pooled over both feet, so a scale error of one foot's sensor counts
    half. (nan, nan, 0) when no stride qualifies."""
    lens, speeds = [], []
    for pre, ic, length in feet:
        pre, ic, length = np.asarray(pre, np.int64), np.asarray(ic, np.int64), np.asarray(length, float)
        ok = (pre >= s0) & (ic <= s1) & (ic > pre) & np.isfinite(length)
        lens.append(length[ok])
        speeds.append(length[ok] / ((ic[ok] - pre[ok]) / fs))
    x, v = np.concatenate(lens), np.concatenate(speeds)
    if not len(x):
        return float("nan"), float("nan"), 0
    return float(np.mean(x)), float(np.mean(v)), int(len(x))


def voisard_foot_reference(t, s0: int, s1: int) -> tuple[float, float, dict]:
    """Spatial reference of one Voisard trial from its two foot MTws: StrideLab's foot INS (``stridelab.estimators.gait.
    foot_kinematics``: adaptive-ZUPT ESKF, stride length between mid-stances; docs/gait.md) -> mean stride length
    and speed over both feet (``foot_stride_reference``). A derived reference, not a gold standard: its own stride
    length error is 1.6-1.9 cm against optical markers on the gaitmap walk (docs/gait.md); the per-trial left /
    right disagreement is reported by the bench (``voisard_foot_reference``)."""
    from stridelab.estimators.gait import foot_kinematics
    feet, per_foot, rows = [], {}, []
    for side, rec in (("left", t.left), ("right", t.right)):
        fk = foot_kinematics(rec.gyr, rec.acc, sampling_rate_hz=rec.sampling_rate_hz)
        st = fk.strides
        pre, ic, ln = st.column("pre_ic"), st.column("ic"), st.column("stride_length_m")
        feet.append((pre, ic, ln))
        per_foot[side] = foot_stride_reference(feet[-1:], s0, s1, rec.sampling_rate_hz)[0]
        ok = (pre >= s0) & (ic <= s1) & (ic > pre) & np.isfinite(ln)
        rows.append(np.column_stack([pre[ok] / rec.sampling_rate_hz, ic[ok] / rec.sampling_rate_hz, ln[ok]]))
    sl, speed, n = foot_stride_reference(feet, s0, s1, t.lower_back.sampling_rate_hz)
    per_foot["n_strides"] = n
    per_foot["strides"] = np.concatenate(rows)
    return sl, speed, per_foot


def load_voisard(directory: Path, failed: list, limit: int | None, foot_reference: bool = True) -> list[Rec]:
    from stridelab.pipeline.formats.xsens_mt import load_voisard_trial
    names = sorted((p.stem for p in directory.glob("*-*.json") if p.stem.replace("-", "").isdigit()),
                   key=lambda s: tuple(int(x) for x in s.split("-")))
    if not names:
        raise UserError(f"{directory}: no N-M.json files; expected the Voisard et al. gait data")
    out = []
    for n in names[:limit] if limit else names:
        try:
            t = load_voisard_trial(directory, n)
            if t.lower_back is None:
                raise ValueError(f"{directory / (n + '_lb.txt')}: missing (no lower-back sensor)")
            check_units(t.lower_back.acc, t.lower_back.gyr, t.lower_back.sampling_rate_hz)
        except (ValueError, OSError, KeyError, IndexError) as e:
            failed.append({"file": str(directory / f"{n}_lb.txt"), "reason": str(e)})
            _say(f"[yellow]skipped Voisard {n}: {e}[/]")
            continue
        a, lb = t.annotation, t.lower_back
        fs = lb.sampling_rate_hz
        s0, s1 = (int(x) for x in a.trial_boundaries)
        hs = np.sort(np.r_[a.left_events[:, 1], a.right_events[:, 1]])
        hs = hs[(hs >= s0) & (hs <= s1)] / fs
        if len(hs) < 3:
            failed.append({"file": str(directory / f"{n}.json"), "reason": "fewer than 3 heel strikes in the trial"})
            continue
        cad = 60.0 * (len(hs) - 1) / (hs[-1] - hs[0])
        sl_ref, speed_ref, per_foot = voisard_foot_reference(t, s0, s1) if foot_reference else (np.nan, np.nan, {})
        out.append(Rec(name=f"voisard:{n}", dataset="voisard", group=f"voisard:S{a.subject}", trial_group=n,
                       acc=lb.acc, gyr=lb.gyr, fs=fs,
                       height_m=a.height_cm / 100.0 if np.isfinite(a.height_cm) else None, leg_length_m=None,
                       ref_ic_s=hs, ref_bouts={"start_s": hs[:1], "end_s": hs[-1:], "cadence_spm": np.array([cad]),
                                               "stride_length_m": np.array([sl_ref]),
                                               "walking_speed_m_s": np.array([speed_ref])},
                       window_s=(s0 / fs, s1 / fs), mobgap_axes=XSENS_TO_MOBGAP,
                       foot_reference={k: v for k, v in per_foot.items() if k != "strides"},
                       foot_strides=per_foot.get("strides"),
                       turn_s=tuple(float(x) / fs for x in a.uturn_boundaries)))
    return out


def load_mobilised(root: Path, failed: list) -> list[Rec]:
    from stridelab.pipeline.formats.mobilised import find_mobilised_files, read_mobilised
    try:
        files = find_mobilised_files(root)
    except ValueError as e:
        raise UserError(str(e)) from e
    out = []
    for f in files:
        try:
            trials = read_mobilised(f)
        except (ValueError, OSError, KeyError, IndexError) as e:
            failed.append({"file": str(f), "reason": str(e)})
            _say(f"[yellow]skipped {f}: {e}[/]")
            continue
        for t in trials:
            try:
                check_units(t.acc, t.gyr, t.fs_hz)
            except ValueError as e:
                failed.append({"file": f"{f}:{t.name}", "reason": str(e)})
                continue
            ref = t.reference("INDIP", "MicroWB")
            if ref is None:
                failed.append({"file": f"{f}:{t.name}", "reason": "no INDIP MicroWB reference"})
                continue
            out.append(Rec(name=f"mobilised:{t.name}", dataset="mobilised", group=f"mobilised:{t.participant_id}",
                           trial_group=t.name, acc=t.acc, gyr=t.gyr, fs=t.fs_hz, height_m=t.info.height_m,
                           leg_length_m=t.info.leg_length_m, ref_ic_s=np.sort(ref.ic_s),
                           ref_bouts={"start_s": ref.start_s, "end_s": ref.end_s, "cadence_spm": ref.cadence_spm,
                                      "stride_length_m": ref.stride_length_m,
                                      "walking_speed_m_s": ref.walking_speed_m_s},
                           window_s=(0.0, len(t.acc) / t.fs_hz), sensor_height_m=t.info.sensor_height_m,
                           ic_windows_s=np.column_stack([ref.start_s, ref.end_s]).astype(float)))
    return out


# ----------------------------------------------------------------------------------------------------- scoring

@dataclass
class Det:
    """What a method found on one recording (times in s)."""
    ic_s: np.ndarray
    bouts: dict             # start_s, end_s, cadence_spm, stride_length_m, walking_speed_m_s
    cadence_by_method: dict = field(default_factory=dict)   # ours: per-bout cadence of each CADENCE_METHODS
    strides: dict | None = None   # start_s, end_s, length_m of the strides in bouts (ours only)
    ic_kind: np.ndarray | None = None   # ours: how each contact was found (index into _icd.IC_KINDS)


def _with_cadence(d: Det, method: str | None) -> Det:
    if method is None or method not in d.cadence_by_method:
        return d
    return dataclasses.replace(d, bouts={**d.bouts, "cadence_spm": d.cadence_by_method[method]})


def _ic_counts(rec: Rec, ic_s: np.ndarray, whole: bool = False) -> tuple[int, int, int, np.ndarray]:
    """Contacts scored inside the reference's walking (± the tolerance): the Voisard trial, the Mobilise-D
    reference walking bouts (``whole``: the whole recording, as before 2026-12-07)."""
    from stridelab.estimators.trunk_gait.evaluation import match_initial_contacts
    win = (np.array([rec.window_s]) if whole or rec.ic_windows_s is None or not len(rec.ic_windows_s)
           else rec.ic_windows_s)
    m = match_initial_contacts(ic_s, rec.ref_ic_s, windows_s=win)
    return len(m.det_idx), len(m.fp_idx), len(m.fn_idx), m.error_s


def _bout_errs(rec: Rec, det: Det, sl_scale: float = 1.0) -> dict:
    from stridelab.estimators.trunk_gait.evaluation import bout_errors, match_bouts
    b = det.bouts
    m = match_bouts(b["start_s"], b["end_s"], rec.ref_bouts["start_s"], rec.ref_bouts["end_s"])
    d = {"cadence_spm": b["cadence_spm"], "stride_length_m": np.asarray(b["stride_length_m"]) * sl_scale,
         "walking_speed_m_s": np.asarray(b["walking_speed_m_s"]) * sl_scale}
    e = bout_errors(m, d, rec.ref_bouts)
    e["_n_ref"] = len(rec.ref_bouts["start_s"])
    e["_n_matched"] = len(m.det_idx)
    return e


def _ic_pooled(recs: list[Rec], dets: list[Det], offset_s: float, whole: bool = False) -> tuple:
    """Contacts matched one-to-one (``_ic_counts``) pooled over ``recs``: TP, FP, FN and the timing errors, s."""
    tp = fp = fn = 0
    errs = []
    for r, d in zip(recs, dets):
        a, b, c, e = _ic_counts(r, d.ic_s + offset_s, whole)
        tp, fp, fn = tp + a, fp + b, fn + c
        errs.append(e)
    return tp, fp, fn, (np.concatenate(errs) if errs else np.empty(0))


def score(recs: list[Rec], dets: list[Det], *, offset_s: float = 0.0, sl_scale: float = 1.0,
          whole: bool = False) -> dict:
    """The six keys (None where no reference) pooled over ``recs``, plus counts."""
    from stridelab.estimators.trunk_gait.evaluation import summarise_bout_errors
    tp, fp, fn, e = _ic_pooled(recs, dets, offset_s, whole)
    berrs = []
    n_ref_b = n_match_b = 0
    for r, d in zip(recs, dets):
        be = _bout_errs(r, d, sl_scale)
        n_ref_b += be.pop("_n_ref")
        n_match_b += be.pop("_n_matched")
        berrs.append(be)
    s = summarise_bout_errors(berrs)
    out = {"ic_sensitivity": tp / (tp + fn) if tp + fn else None, "ic_precision": tp / (tp + fp) if tp + fp else None,
           "ic_timing_mae_ms": float(np.mean(np.abs(e)) * 1000) if len(e) else None,
           "cadence_mape_pct": s["cadence_mape_pct"], "stride_length_mae_m": s["stride_length_mae_m"],
           "walking_speed_mae_m_s": s["walking_speed_mae_m_s"],
           "ic_timing_bias_ms": float(np.mean(e) * 1000) if len(e) else None,
           "n_recordings": len(recs), "ic_tp": tp, "ic_fp": fp, "ic_fn": fn,
           "bouts_reference": n_ref_b, "bouts_matched": n_match_b,
           "bouts_with_stride_length_reference": s["n_bouts_stride_length"]}
    return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in out.items()}


def blocks(recs: list[Rec], dets: list[Det], *, offsets=None, sl_scales=None) -> dict:
    """Per data set and overall. ``offsets`` / ``sl_scales``: per-recording values (held-out choices) or None."""
    offsets = offsets if offsets is not None else [0.0] * len(recs)
    sl_scales = sl_scales if sl_scales is not None else [1.0] * len(recs)
    out = {}
    for ds in ("voisard", "mobilised"):
        idx = [i for i, r in enumerate(recs) if r.dataset == ds]
        if idx:
            out[ds] = _score_idx(recs, dets, idx, offsets, sl_scales)
    out["overall"] = _score_idx(recs, dets, list(range(len(recs))), offsets, sl_scales)
    idx = [i for i, r in enumerate(recs) if r.dataset == "mobilised"]
    if idx:     # contacts over the whole recording (walking INDIP leaves out of its bouts counts as extra)
        out["mobilised_whole_recording"] = {k: v for k, v in _score_idx(recs, dets, idx, offsets, sl_scales,
                                                                           whole=True).items()
                                            if k.startswith("ic_")}
    return out


def _score_idx(recs, dets, idx, offsets, sl_scales, whole: bool = False) -> dict:
    # recordings can carry different offsets/scales (held-out choices): shift the detections, then pool
    shifted = [Det(ic_s=dets[i].ic_s + offsets[i],
                   bouts={**dets[i].bouts,
                          "stride_length_m": np.asarray(dets[i].bouts["stride_length_m"]) * sl_scales[i],
                          "walking_speed_m_s": np.asarray(dets[i].bouts["walking_speed_m_s"]) * sl_scales[i]})
               for i in idx]
    return score([recs[i] for i in idx], shifted, whole=whole)


def sl_mae(recs: list[Rec], dets: list[Det], sl_scale: float = 1.0) -> float:
    """Per-bout stride-length MAE (m) of matched bouts pooled over ``recs`` (inf when none has a reference)."""
    return spatial_mae(recs, dets, sl_scale, "stride_length_m")


def ic_score(recs: list[Rec], dets: list[Det], *, offset_s: float = 0.0) -> dict:
    """The contact counts and timing MAE of ``score`` alone (``ic_tp``, ``ic_fp``, ``ic_fn``, ``ic_timing_mae_ms``,
    rounded as there): what ``ic_loss`` reads, without the bout matching that does not depend on the offset (the
    IC grid scores every candidate at every offset of GRID_OFFSET_S; 2026-12-08, same losses as before)."""
    tp, fp, fn, e = _ic_pooled(recs, dets, offset_s)
    return {"ic_tp": tp, "ic_fp": fp, "ic_fn": fn,
            "ic_timing_mae_ms": round(float(np.mean(np.abs(e)) * 1000), 4) if len(e) else None}


def ic_loss(s: dict) -> float:
    """Timing cost per reference contact, ms: a matched contact costs its timing error, a missed or an extra one
    the matching tolerance (250 ms), i.e. (Σ|e| + 250 (FN + FP)) / (TP + FN)."""
    from stridelab.estimators.trunk_gait.evaluation import IC_TOLERANCE_S
    n_ref = s["ic_tp"] + s["ic_fn"]
    if s["ic_timing_mae_ms"] is None or not n_ref:
        return float("inf")
    return (s["ic_timing_mae_ms"] * s["ic_tp"] + 1000.0 * IC_TOLERANCE_S * (s["ic_fn"] + s["ic_fp"])) / n_ref


# ----------------------------------------------------------------------------------------------- our method

def _detector_name(p) -> str:
    cad = f"; cadence_method {p.cadence_method}"
    if p.ic_method in ("shin", "hklee"):
        src = ("Shin & Park 2011 improved: rising zero crossings" if p.ic_method == "shin" else
               "Lee et al. 2010 improved: closing-minus-opening maxima")
        ref = f", timed by the upward-acceleration peak within {p.ic_refine_s} s" if p.ic_refine_s > 0 else ""
        return (f"{p.ic_method} ({src} of the doubly wavelet-filtered acceleration {p.ic_cwt_signal}{ref}), "
                f"offset {p.ic_offset_s} s" + cad)
    if p.ic_method == "ionescu":
        return (f"ionescu (Paraschiv-Ionescu et al. 2020: jerk-lobe minima, sigma {p.ic_zc_sigma_s} s, "
                f"min depth {p.ic_zc_min_depth} SD), offset {p.ic_offset_s} s" + cad)
    fill = (f", fill of missed steps at {p.ic_fill_prominence} SD (edge {p.ic_fill_edge_steps}, closing "
            f"{p.ic_fill_end_steps})" if p.ic_fill_prominence > 0 else "")
    if p.ic_turn_prominence != 1.0:
        fill += f", threshold x {p.ic_turn_prominence} in turns"
    if p.ic_fill_start_prominence > 0:
        fill += f", first step of a walk filled at {p.ic_fill_start_prominence} SD"
    if p.ic_subsample:
        fill += ", sub-sample peak (parabola vertex)"
    if p.ic_fill_end_rhythm and p.ic_fill_prominence > 0 and p.ic_fill_end_steps > 0:
        fill += ", first closing step one median step after the last contact"
        if p.ic_fill_walk_ends:
            fill += " of every walk"
    if p.stride_rule != "run":
        fill += f", stride rule {p.stride_rule}"
    return (f"peak (McCamley et al. 2012 / Zijlstra & Hof 2003: smoothed upward-acceleration peak, sigma "
            f"{p.ic_smooth_s} s, prominence {p.ic_prominence} SD{fill}), offset {p.ic_offset_s} s" + cad)


def run_ours(rec: Rec, params) -> Det:
    from stridelab.estimators.trunk_gait import analyse_trunk_gait
    res = analyse_trunk_gait(rec.acc, rec.gyr, rec.fs, placement="lower_back", height_m=rec.height_m,
                             leg_length_m=rec.leg_length_m, params=params)
    from stridelab.estimators.trunk_gait._pipeline import bout_cadence
    b = res.bouts
    ic = res.initial_contacts_s
    if res.ic_kind is not None:       # the estimator's cadence uses the times without the per-kind offsets
        from stridelab.estimators.trunk_gait._icd import kind_offsets_s
        ic = ic - kind_offsets_s(res.ic_kind, fill_offset_s=params.ic_fill_offset_s,
                                 walk_end_offset_s=params.ic_walk_end_offset_s)
    if res.ic_closing is not None:          # closing steps are no steps of the cadence (as in the estimator)
        ic = ic[~res.ic_closing]
    cad = {m: np.array([bout_cadence(ic[(ic >= s - 1e-9) & (ic <= e + 1e-9)], max_step_s=params.stride_max_s / 2.0,
                                     method=m) for s, e in zip(b.start_s, b.end_s)]) for m in CADENCE_METHODS}
    st = res.strides
    return Det(ic_s=res.initial_contacts_s, bouts={"start_s": b.start_s, "end_s": b.end_s,
                               "cadence_spm": b.cadence_spm, "stride_length_m": b.stride_length_m,
                               "walking_speed_m_s": b.walking_speed_m_s}, cadence_by_method=cad,
               strides={"start_s": st.start_s, "end_s": st.end_s, "length_m": st.length_m, "bout": st.bout,
                        "tilt_deg": st.tilt_deg, "steady": st.steady}, ic_kind=res.ic_kind)


def respatial(det: Det, average: str, strides: str, speed_method: str, max_tilt_deg: float = 0.0) -> Det:
    """``det`` with its bouts' stride length and speed recomputed from its strides by the estimator's
    ``bout_spatial`` (bout average, strides used, speed method; the speed's cadence is the bouts' "count" cadence,
    steps over walking time, as in the estimator whatever cadence the bouts report; strides over a stop left out)."""
    from stridelab.estimators.trunk_gait._pipeline import bout_spatial
    st = det.strides
    if st is None:
        return det
    cad = det.cadence_by_method.get("count", det.bouts["cadence_spm"])   # speed: steps over walking time
    sl, sp = bout_spatial(st["length_m"], st["end_s"] - st["start_s"], st["bout"],
                          np.asarray(cad, float), average=average, strides=strides,
                          speed_method=speed_method, tilt_deg=st["tilt_deg"], max_tilt_deg=max_tilt_deg,
                          steady=st.get("steady"))
    return dataclasses.replace(det, bouts={**det.bouts, "stride_length_m": sl, "walking_speed_m_s": sp})


def turn_check(recs: list[Rec], shipped) -> dict | None:
    """Median ratio ours / foot-INS stride length of the Voisard strides inside the annotated U-turn and outside it,
    with the shipped defaults and with the turn shortening off (what ``sl_turn_per_rad`` corrects)."""
    out = {}
    for label, c in (("shipped", shipped.sl_turn_per_rad), ("turn_shortening_off", 0.0)):
        ins, outs = [], []
        for r in recs:
            if r.foot_strides is None or r.turn_s is None:
                continue
            d = run_ours(r, dataclasses.replace(shipped, sl_turn_per_rad=c))
            o, rf, mid = stride_pairs(r, d, with_mid=True)
            t = (mid >= r.turn_s[0]) & (mid <= r.turn_s[1])
            ins.append(o[t] / rf[t])
            outs.append(o[~t] / rf[~t])
        if not ins:
            return None
        i, o = np.concatenate(ins), np.concatenate(outs)
        out[label] = {"u_turn_strides": int(len(i)), "straight_strides": int(len(o)),
                      "u_turn_ratio_median": round(float(np.median(i)), 3) if len(i) else None,
                      "straight_ratio_median": round(float(np.median(o)), 3) if len(o) else None}
    out["note"] = "ours / foot-INS stride length per matched stride, Voisard, U-turn = UTurnBoundaries (in-sample)"
    return out


def stride_pairs(rec: Rec, det: Det, tol_s: float = 0.3, with_mid: bool = False):
    """(ours, reference) stride lengths of the trunk strides matched to a foot stride of ``rec.foot_strides``
    (same-foot contact to contact, so the nearest midpoint within ``tol_s``; the other foot's strides are half a
    stride away)."""
    fr = rec.foot_strides
    if fr is None or not len(fr) or det.strides is None or not len(det.strides["start_s"]):
        return (np.empty(0),) * (3 if with_mid else 2)
    mid = (det.strides["start_s"] + det.strides["end_s"]) / 2
    fmid = (fr[:, 0] + fr[:, 1]) / 2
    j = np.argmin(np.abs(mid[:, None] - fmid[None, :]), axis=1)
    ok = (np.abs(mid - fmid[j]) <= tol_s) & np.isfinite(det.strides["length_m"])
    res = (np.asarray(det.strides["length_m"], float)[ok], fr[j[ok], 2])
    return (*res, mid[ok]) if with_mid else res


def ic_context(recs: list[Rec], dets: list[Det], offsets=None) -> dict:
    """Where the contacts are missed and found extra: Voisard by the part of the trial (the first and the last
    heel strike, inside the annotated U-turn, the straight walk); Mobilise-D per INDIP reference walking bout
    (its duration, speed, cadence, contacts found / missed / extra). ``offsets``: per-recording held-out offsets."""
    from stridelab.estimators.trunk_gait.evaluation import match_initial_contacts
    offsets = offsets if offsets is not None else [0.0] * len(recs)
    vo = {k: {"reference": 0, "missed": 0} for k in ("first", "last", "u_turn", "straight")}
    vo_fp = {"u_turn": 0, "straight": 0}
    bouts = []
    for r, d, o in zip(recs, dets, offsets):
        win = r.ic_windows_s if r.ic_windows_s is not None and len(r.ic_windows_s) else np.array([r.window_s])
        m = match_initial_contacts(d.ic_s + o, r.ref_ic_s, windows_s=win)
        missed = np.zeros(len(r.ref_ic_s), bool)
        missed[m.fn_idx] = True
        if r.dataset == "voisard":
            part = np.full(len(r.ref_ic_s), "straight", dtype=object)
            if r.turn_s is not None:
                part[(r.ref_ic_s >= r.turn_s[0]) & (r.ref_ic_s <= r.turn_s[1])] = "u_turn"
            part[0], part[-1] = "first", "last"
            for k in vo:
                vo[k]["reference"] += int(np.sum(part == k))
                vo[k]["missed"] += int(np.sum(missed & (part == k)))
            fp_t = (d.ic_s + o)[m.fp_idx]
            in_turn = ((fp_t >= r.turn_s[0]) & (fp_t <= r.turn_s[1])) if r.turn_s is not None else np.zeros(0, bool)
            vo_fp["u_turn"] += int(in_turn.sum())
            vo_fp["straight"] += int(len(fp_t) - in_turn.sum())
        else:
            fp_t = (d.ic_s + o)[m.fp_idx]
            b = r.ref_bouts
            for k, (st, en) in enumerate(zip(b["start_s"], b["end_s"])):
                inb = (r.ref_ic_s >= st - 1e-6) & (r.ref_ic_s <= en + 1e-6)
                bouts.append({"recording": r.name, "start_s": round(float(st), 2),
                              "duration_s": round(float(en - st), 2),
                              "walking_speed_m_s": round(float(b["walking_speed_m_s"][k]), 3),
                              "cadence_spm": round(float(b["cadence_spm"][k]), 1), "reference": int(inb.sum()),
                              "missed": int((inb & missed).sum()),
                              "missed_at_s": [round(float(x), 2) for x in r.ref_ic_s[inb & missed]],
                              "extra": int(np.sum((fp_t >= st - 0.25) & (fp_t <= en + 0.25)))})
    out = {}
    if any(v["reference"] for v in vo.values()):
        out["voisard"] = {k: {**v, "sensitivity": round(1 - v["missed"] / v["reference"], 4) if v["reference"]
                              else None} for k, v in vo.items()}
        out["voisard_extra"] = vo_fp
    if bouts:
        out["mobilised_reference_bouts"] = bouts
    return out


def ic_timing_by_kind(recs: list[Rec], dets: list[Det], offsets=None) -> dict:
    """Timing error of the matched contacts by how each was found (``Det.ic_kind``: a threshold peak, a gap fill, an
    edge or start fill, a closing step placed by the rhythm or at a weak peak), the threshold peak right before a
    closing step counted apart ("peak_before_closing": the step that stops a walk); per data set: matched, extra,
    timing MAE and bias (ms), and the sum of |error| (the share of the timing MAE). ``offsets``: per-recording
    held-out offsets."""
    from stridelab.estimators.trunk_gait._icd import IC_KINDS
    from stridelab.estimators.trunk_gait.evaluation import match_initial_contacts
    offsets = offsets if offsets is not None else [0.0] * len(recs)
    closing_k = (IC_KINDS.index("closing_rhythm"), IC_KINDS.index("closing_peak"))
    acc: dict = {}
    for r, d, o in zip(recs, dets, offsets):
        if d.ic_kind is None:
            continue
        k = np.asarray(d.ic_kind)
        lab = np.array([IC_KINDS[x] for x in k], dtype=object)
        before = np.flatnonzero(np.isin(k[1:], closing_k) & (k[:-1] == 0)) if len(k) > 1 else np.empty(0, int)
        lab[before] = "peak_before_closing"
        win = r.ic_windows_s if r.ic_windows_s is not None and len(r.ic_windows_s) else np.array([r.window_s])
        m = match_initial_contacts(d.ic_s + o, r.ref_ic_s, windows_s=win)
        a = acc.setdefault(r.dataset, {"missed": 0, "kinds": {}})
        a["missed"] += len(m.fn_idx)
        for i, e in zip(m.det_idx, m.error_s):
            a["kinds"].setdefault(lab[i], {"e": [], "extra": 0})["e"].append(e)
        for i in m.fp_idx:
            a["kinds"].setdefault(lab[i], {"e": [], "extra": 0})["extra"] += 1
    out = {}
    for ds, a in acc.items():
        n_all = sum(len(v["e"]) for v in a["kinds"].values())
        rows = {}
        for kind in (*IC_KINDS[:1], "peak_before_closing", *IC_KINDS[1:]):
            if kind not in a["kinds"]:
                continue
            e = 1000.0 * np.asarray(a["kinds"][kind]["e"], float)
            rows[kind] = {"matched": int(len(e)), "extra": a["kinds"][kind]["extra"],
                          "timing_mae_ms": round(float(np.mean(np.abs(e))), 1) if len(e) else None,
                          "timing_bias_ms": round(float(np.mean(e)), 1) if len(e) else None,
                          "share_of_timing_mae_ms": round(float(np.sum(np.abs(e))) / n_all, 2) if n_all else None}
        out[ds] = {"missed": a["missed"], "by_kind": rows}
    return out


def cadence_by_reference_bout(recs: list[Rec], dets: list[Det], params) -> list[dict]:
    """Mobilise-D per INDIP reference bout: its cadence, the matched bout of ours (start, end, cadence), and the
    ``params.cadence_method`` cadence of our own contacts inside the reference bout (± 0.15 s; closing steps left out,
    per-kind offsets removed as in the estimator): where the two differ, the error comes from where our bout begins
    and ends, not from the contacts or the formula (2026-12-08 cadence diagnosis)."""
    from stridelab.estimators.trunk_gait._icd import IC_KINDS, kind_offsets_s
    from stridelab.estimators.trunk_gait._pipeline import bout_cadence
    from stridelab.estimators.trunk_gait.evaluation import match_bouts
    closing_k = (IC_KINDS.index("closing_rhythm"), IC_KINDS.index("closing_peak"))
    rows = []
    for r, d in zip(recs, dets):
        if r.dataset != "mobilised":
            continue
        ic = np.asarray(d.ic_s, float)
        if d.ic_kind is not None:
            k = np.asarray(d.ic_kind)
            ic = (ic - kind_offsets_s(k, fill_offset_s=params.ic_fill_offset_s,
                                      walk_end_offset_s=params.ic_walk_end_offset_s))[~np.isin(k, closing_k)]
        b, rb = d.bouts, r.ref_bouts
        m = match_bouts(b["start_s"], b["end_s"], rb["start_s"], rb["end_s"])
        ours = dict(zip(m.ref_idx.tolist(), m.det_idx.tolist()))
        for j, (st, en) in enumerate(zip(rb["start_s"], rb["end_s"])):
            inside = ic[(ic >= st - 0.15) & (ic <= en + 0.15)]
            c_in = bout_cadence(inside, max_step_s=params.stride_max_s / 2.0, method=params.cadence_method)
            ref_c = float(rb["cadence_spm"][j])
            row = {"recording": r.name, "reference_s": [round(float(st), 2), round(float(en), 2)],
                   "reference_cadence_spm": round(ref_c, 1),
                   "ours_inside_reference_bout_spm": round(c_in, 1) if np.isfinite(c_in) else None,
                   "ours_inside_error_pct": round(100 * (c_in - ref_c) / ref_c, 1) if np.isfinite(c_in) else None,
                   "ours_bout_s": None, "ours_bout_cadence_spm": None, "ours_bout_error_pct": None}
            if j in ours:
                i = ours[j]
                c = float(b["cadence_spm"][i])
                row.update({"ours_bout_s": [round(float(b["start_s"][i]), 2), round(float(b["end_s"][i]), 2)],
                            "ours_bout_cadence_spm": round(c, 1),
                            "ours_bout_error_pct": round(100 * (c - ref_c) / ref_c, 1) if np.isfinite(c) else None})
            rows.append(row)
    return rows


def _logo(groups: list[str], loss_fn, n_cand: int) -> dict:
    """Leave-one-group-out: ``loss_fn(group_list, c)`` pooled loss of candidate c on those groups."""
    ug = sorted(set(groups))
    held = {}
    for g in ug:
        train = [x for x in ug if x != g] or [g]      # a single group: nothing to hold out (in-sample)
        losses = [loss_fn(train, c) for c in range(n_cand)]
        held[g] = int(np.argmin(losses))
    ins = int(np.argmin([loss_fn(ug, c) for c in range(n_cand)]))
    return {"held_out_choice": held, "in_sample_choice": ins}


def choose_turn(recs: list[Rec], shipped, groups: list[str]) -> float:
    """``sl_turn_per_rad`` chosen on ``groups`` at the stride level: every trunk stride matched to a foot-INS stride
    (``stride_pairs``; Voisard), Hampel off; per candidate the factor K = median reference / ours pooled over the
    groups, loss = mean over groups of the stride-length MAE after K. Bout means cannot tell it: every Voisard
    trial holds one U-turn, so sl_correction absorbs a constant turning bias. The shipped value when no group has
    foot strides."""
    grid = sorted(SL_TURN_GRID)
    pairs = {c: {} for c in grid}
    for i, r in enumerate(recs):
        if r.group in groups and r.foot_strides is not None:
            for c in grid:
                pairs[c][i] = stride_pairs(r, _turn_det(r, shipped, c))
    gs = sorted({recs[i].group for i in pairs[grid[0]]})
    if not gs:
        return shipped.sl_turn_per_rad

    def loss(c):
        o = np.concatenate([pairs[c][i][0] for i in pairs[c]])
        rf = np.concatenate([pairs[c][i][1] for i in pairs[c]])
        if not len(o):
            return float("inf")
        k = float(np.median(rf / o))
        per_g = []
        for g in gs:
            e = [np.abs(k * pairs[c][i][0] - pairs[c][i][1]) for i in pairs[c] if recs[i].group == g]
            e = np.concatenate(e) if e else np.empty(0)
            if len(e):
                per_g.append(float(np.mean(e)))
        return float(np.mean(per_g)) if per_g else float("inf")
    return float(grid[int(np.argmin([loss(c) for c in grid]))])


_TURN_DETS: dict = {}


def _turn_det(r: Rec, shipped, c: float) -> Det:
    key = (r.name, c, shipped)
    if key not in _TURN_DETS:
        _TURN_DETS[key] = run_ours(r, dataclasses.replace(shipped, sl_hampel_half_width=0, sl_turn_per_rad=c))
    return _TURN_DETS[key]


def matched_values(recs: list[Rec], dets: list[Det], key: str) -> tuple[np.ndarray, np.ndarray]:
    """(ours, reference) ``key`` of every matched bout with a finite reference, pooled over ``recs``."""
    from stridelab.estimators.trunk_gait.evaluation import match_bouts
    det, ref = [], []
    for r, d in zip(recs, dets):
        b = d.bouts
        m = match_bouts(b["start_s"], b["end_s"], r.ref_bouts["start_s"], r.ref_bouts["end_s"])
        x = np.asarray(b[key], float)[m.det_idx]
        y = np.asarray(r.ref_bouts[key], float)[m.ref_idx]
        ok = np.isfinite(x) & np.isfinite(y)
        det.append(x[ok])
        ref.append(y[ok])
    return (np.concatenate(det), np.concatenate(ref)) if det else (np.empty(0), np.empty(0))


def spatial_mae(recs: list[Rec], dets: list[Det], sl_scale: float, key: str) -> float:
    """Per-bout MAE of ``key`` ("stride_length_m" | "walking_speed_m_s") of the matched bouts pooled over ``recs``
    (inf when none has a reference)."""
    e = [np.asarray(_bout_errs(r, d, sl_scale).get(key, {}).get("abs_error", []), float) for r, d in zip(recs, dets)]
    x = np.concatenate(e) if e else np.empty(0)
    x = x[np.isfinite(x)]
    return float(np.mean(x)) if len(x) else float("inf")


def choose_spatial(recs: list[Rec], shipped) -> tuple[dict, tuple | None]:
    """Stride length and speed: every recording with a spatial reference (Voisard: foot INS; Mobilise-D: INDIP);
    leave-one-group-out over the same groups as the IC constants (9 Voisard subjects + the Mobilise-D participant).
    Per fold, first the turn shortening ``sl_turn_per_rad`` at the stride level (``choose_turn``), then, with it,
    the Hampel half width x bout mean/median x regular/all strides (SL_VARIANTS) and the factor sl_correction
    (GRID_SL) at the bout level (loss = mean over groups of the group's per-bout stride-length MAE), then with those
    the speed method (SPEED_METHODS; loss = mean over groups of the group's per-bout speed MAE); the IC constants as
    shipped. Returns ({group: ((half_width, average, turn_per_rad, bout_strides), sl_correction, speed_method)
    chosen without it}, the in-sample choice or None)."""
    sp = [i for i, r in enumerate(recs) if np.isfinite(np.asarray(r.ref_bouts["stride_length_m"], float)).any()]
    if not sp:
        return {}, None
    # the estimator runs once per (Hampel, turn); the bout aggregation is recomputed from its strides
    base = {(h, c): {i: run_ours(recs[i], dataclasses.replace(shipped, sl_hampel_half_width=h, sl_turn_per_rad=c))
                     for i in sp} for h in sorted({v[0] for v in SL_VARIANTS}) for c in SL_TURN_GRID}

    def det_of(v: tuple, i: int, speed_method: str) -> Det:
        return respatial(base[(v[0], v[2])][i], v[1], v[3], speed_method, v[4])
    ks = np.asarray(GRID_SL, float)
    sl_cache: dict = {}

    def sl_group(g, v) -> np.ndarray:
        """(len(GRID_SL),) the group's per-bout stride-length MAE for every K (the bout values scale with K)."""
        if (g, v) not in sl_cache:
            idx = [i for i in sp if recs[i].group == g]
            det, ref = matched_values([recs[i] for i in idx], [det_of(v, i, shipped.speed_method) for i in idx],
                                      "stride_length_m")
            sl_cache[(g, v)] = (np.mean(np.abs(np.outer(ks / shipped.sl_correction, det) - ref[None, :]), axis=1)
                                if len(det) else np.full(len(ks), np.inf))
        return sl_cache[(g, v)]

    def mean_finite(x: list[float]) -> float:
        x = [y for y in x if np.isfinite(y)]
        return float(np.mean(x)) if x else float("inf")

    def choose(train: list[str]) -> tuple:
        turn = choose_turn(recs, shipped, train)
        best = (np.inf, None, None)
        for v in (v for v in SL_VARIANTS if v[2] == turn):       # first minimum in grid order wins ties
            per_g = np.array([sl_group(g, v) for g in train])
            per_g = np.where(np.isfinite(per_g), per_g, np.nan)
            loss = np.nanmean(per_g, axis=0) if np.isfinite(per_g).any() else np.full(len(ks), np.inf)
            j = int(np.nanargmin(loss)) if np.isfinite(loss).any() else 0
            if loss[j] < best[0]:
                best = (float(loss[j]), v, float(ks[j]))
        _l, v, k = best

        def speed_loss(m: str) -> float:
            return mean_finite([spatial_mae([recs[i] for i in sp if recs[i].group == g],
                                            [det_of(v, i, m) for i in sp if recs[i].group == g],
                                            k / shipped.sl_correction, "walking_speed_m_s") for g in train])
        return v, k, min(SPEED_METHODS, key=speed_loss)
    groups = sorted({recs[i].group for i in sp})
    held = {g: choose([x for x in groups if x != g] or [g]) for g in groups}
    return held, choose(groups)


def tilt_gate_check(recs: list[Rec], shipped) -> dict | None:
    """In-sample: the shipped defaults with the trunk-lean gate ``sl_max_tilt_deg`` on (strides leaning more than
    the gate from the walking posture left out of the bout values) per data set, and how far strides lean
    (``Strides.tilt_deg`` percentiles). Not chosen by the leave-one-group-out (see SL_TILT_GATES)."""
    idx = [i for i, r in enumerate(recs) if np.isfinite(np.asarray(r.ref_bouts["stride_length_m"], float)).any()]
    if not idx:
        return None
    dets = {i: run_ours(recs[i], shipped) for i in idx}
    out = {"marked": "in-sample, shipped defaults, no re-tuning of K", "tilt_deg_percentiles_50_90_99_max": {}}
    for ds in ("voisard", "mobilised"):
        ii = [i for i in idx if recs[i].dataset == ds]
        if not ii:
            continue
        t = np.concatenate([dets[i].strides["tilt_deg"] for i in ii])
        t = t[np.isfinite(t)]
        if len(t):
            out["tilt_deg_percentiles_50_90_99_max"][ds] = [round(float(x), 1) for x in
                                                            np.percentile(t, [50, 90, 99, 100])]
        for g in (0.0, *SL_TILT_GATES):
            d = [respatial(dets[i], shipped.bout_average, shipped.bout_strides, shipped.speed_method, g) for i in ii]
            sub = [recs[i] for i in ii]
            out.setdefault(f"gate_{g:g}_deg" if g else "gate_off", {})[ds] = {
                "stride_length_mae_m": round(spatial_mae(sub, d, 1.0, "stride_length_m"), 4),
                "walking_speed_mae_m_s": round(spatial_mae(sub, d, 1.0, "walking_speed_m_s"), 4)}
    return out


def sensor_height_check(recs: list[Rec], shipped) -> dict | None:
    """The shipped defaults on the recordings with a measured sensor height (Mobilise-D ``infoForAlgo``) with the
    pendulum length l = that sensor height instead of the leg length (0.53 H) that ``sl_correction`` is calibrated
    with: shows whether the measured height should replace the leg length (it is not used; docs/trunk_gait.md)."""
    idx = [i for i, r in enumerate(recs) if r.sensor_height_m and
           np.isfinite(np.asarray(r.ref_bouts["stride_length_m"], float)).any()]
    if not idx:
        return None
    sub = [recs[i] for i in idx]
    leg = [run_ours(r, shipped) for r in sub]
    sens = [run_ours(dataclasses.replace(r, leg_length_m=r.sensor_height_m), shipped) for r in sub]
    return {"recordings": len(sub), "sensor_height_m": sorted({round(r.sensor_height_m, 3) for r in sub}),
            "height_m": sorted({r.height_m for r in sub if r.height_m}),
            "stride_length_mae_m_leg_length": round(sl_mae(sub, leg), 4),
            "stride_length_mae_m_sensor_height": round(sl_mae(sub, sens), 4),
            "note": "shipped defaults, in-sample on these recordings; l = 0.53 H (shipped) vs l = measured sensor "
                    "height with the same sl_correction"}


def tune_and_score(recs: list[Rec], show: bool, candidates: tuple = IC_CANDIDATES_PEAK) -> dict:
    """Run our estimator for the IC grid (``candidates``: the "peak" candidates, or ``IC_CANDIDATES`` with the
    other detectors), choose constants by LOGO, score shipped / CV / in-sample."""
    from stridelab.estimators.trunk_gait import TrunkGaitParams
    shipped = TrunkGaitParams()
    # group-level means of the IC loss: each candidate = (IC detector candidate, offset)
    dets: dict[int, list[Det]] = {}
    # every candidate without the shipped per-kind offsets (chosen in the second stage below, GRID_KIND_OFFSETS)
    for ci, ic in enumerate(candidates):
        dets[ci] = [run_ours(r, dataclasses.replace(shipped, **ic, ic_offset_s=0.0, ic_fill_offset_s=0.0,
                                                    ic_walk_end_offset_s=0.0)) for r in recs]
        if show:
            _say(f"  grid {ci + 1}/{len(candidates)}: " + " ".join(f"{k}={v}" for k, v in ic.items()))
    full = [(ci, o) for ci in range(len(candidates)) for o in GRID_OFFSET_S]
    groups = [r.group for r in recs]
    cache: dict = {}

    def group_loss(g: str, c: int) -> float:
        key = (g, c)
        if key not in cache:
            ci, o = full[c]
            idx = [i for i, r in enumerate(recs) if r.group == g]
            cache[key] = ic_loss(ic_score([recs[i] for i in idx], [dets[ci][i] for i in idx], offset_s=o))
        return cache[key]

    logo = _logo(groups, lambda gs, c: float(np.mean([group_loss(g, c) for g in gs])), len(full))
    # every IC candidate at its best offset, in-sample (group-mean loss over all groups): how the detectors compare
    ug_all = sorted(set(groups))
    grid_table = []
    for ci, ic in enumerate(candidates):
        cs = [c for c, (cj, _o) in enumerate(full) if cj == ci]
        losses = [float(np.mean([group_loss(g, c) for g in ug_all])) for c in cs]
        c = cs[int(np.argmin(losses))]
        sc = score(recs, dets[ci], offset_s=full[c][1])
        grid_table.append({**ic, "ic_offset_s": full[c][1], "loss_ms": round(min(losses), 2),
                           **{k: sc[k] for k in ("ic_sensitivity", "ic_precision", "ic_timing_mae_ms")}})
    # second stage: the per-kind offsets (GRID_KIND_OFFSETS) jointly with ic_offset_s, given each fold's detector
    # candidate, on the same training groups (the first stage's offset is re-chosen with them; (0, 0) is in the grid)
    kdets: dict = {}

    def kdet(ci: int, ko: tuple) -> list[Det]:
        if ko == (0.0, 0.0):
            return dets[ci]
        if (ci, ko) not in kdets:
            kdets[(ci, ko)] = [run_ours(r, dataclasses.replace(shipped, **candidates[ci], ic_offset_s=0.0,
                                                               ic_fill_offset_s=ko[0], ic_walk_end_offset_s=ko[1]))
                               for r in recs]
        return kdets[(ci, ko)]
    kcache: dict = {}

    def kloss(g: str, ci: int, ko: tuple) -> np.ndarray:
        """(len(GRID_OFFSET_S),) the group's IC loss for every ic_offset_s."""
        if (g, ci, ko) not in kcache:
            idx = [i for i, r in enumerate(recs) if r.group == g]
            d = kdet(ci, ko)
            kcache[(g, ci, ko)] = np.array([ic_loss(ic_score([recs[i] for i in idx], [d[i] for i in idx], offset_s=o))
                                            for o in GRID_OFFSET_S])
        return kcache[(g, ci, ko)]

    def kind_grid(ci: int) -> tuple:
        c = candidates[ci]
        return GRID_KIND_OFFSETS if c["ic_method"] == "peak" and c.get("ic_fill_prominence", 0) > 0 else ((0.0, 0.0),)

    def choose_kind(ci: int, train: list[str]) -> tuple[tuple, float, float]:
        """((ic_fill_offset_s, ic_walk_end_offset_s), ic_offset_s, training loss) for candidate ``ci``."""
        best = (None, None, np.inf)
        for ko in kind_grid(ci):
            lo = np.mean([kloss(g, ci, ko) for g in train], axis=0)
            j = int(np.argmin(lo))
            if lo[j] < best[2]:
                best = (ko, float(GRID_OFFSET_S[j]), float(lo[j]))
        return best
    ug0 = sorted(set(groups))
    ic_held = {}
    for g in ug0:
        ci = full[logo["held_out_choice"][g]][0]
        ko, o, _l = choose_kind(ci, [x for x in ug0 if x != g] or [g])
        ic_held[g] = (ci, ko, o)
    ci_in = full[logo["in_sample_choice"]][0]
    ko_in, o_in, _l = choose_kind(ci_in, ug0)
    kind_table = [{"ic_fill_offset_s": ko[0], "ic_walk_end_offset_s": ko[1],
                   "ic_offset_s": float(GRID_OFFSET_S[int(np.argmin(lo))]), "loss_ms": round(float(np.min(lo)), 2)}
                  for ko in kind_grid(ci_in)
                  for lo in [np.mean([kloss(g, ci_in, ko) for g in ug0], axis=0)]]
    ship_dets = [run_ours(r, shipped) for r in recs]
    sl_held, sl_ins = choose_spatial(recs, shipped)
    ship_v = (shipped.sl_hampel_half_width, shipped.bout_average, shipped.sl_turn_per_rad, shipped.bout_strides,
              shipped.sl_max_tilt_deg)
    ship_sp = (ship_v, shipped.sl_correction, shipped.speed_method)

    def with_sl(r: Rec, ci: int, ko: tuple, v: tuple, cad: str, speed_method: str) -> Det:
        """The fold's IC candidate (with its per-kind offsets ``ko``) and spatial variant; the speed after the fold's
        cadence method."""
        d = (kdet(ci, ko)[i_of[r.name]] if v[0] == ship_v[0] and v[2] == ship_v[2] else
             run_ours(r, dataclasses.replace(shipped, **candidates[ci], ic_offset_s=0.0,
                                             ic_fill_offset_s=ko[0], ic_walk_end_offset_s=ko[1],
                                             sl_hampel_half_width=v[0], sl_turn_per_rad=v[2])))
        return respatial(_with_cadence(d, cad), v[1], v[3], speed_method, v[4])
    i_of = {r.name: i for i, r in enumerate(recs)}
    # cadence method: leave-one-group-out on the cadence MAPE of the bouts of the fold's IC choice (nested: the
    # held-out group's IC choice was made without it, its cadence method too)
    def cad_loss(ci: int, ko: tuple, gs: list[str], m: str) -> float:
        idx = [i for i, r in enumerate(recs) if r.group in gs]
        d = kdet(ci, ko)
        v = score([recs[i] for i in idx], [_with_cadence(d[i], m) for i in idx])["cadence_mape_pct"]
        return float("inf") if v is None else float(v)
    ug = sorted(set(groups))
    cad_held = {}
    for g in ug:
        ci, ko, _o = ic_held[g]
        train = [x for x in ug if x != g] or [g]
        cad_held[g] = min(CADENCE_METHODS, key=lambda m: cad_loss(ci, ko, train, m))
    cad_ins = min(CADENCE_METHODS, key=lambda m: cad_loss(ci_in, ko_in, ug, m))
    # cross-validated: per recording, the detections of its held-out choices (IC constants, cadence method and
    # spatial constants each chosen without the recording's group)
    cv_dets, cv_off, cv_scale = [], [], []
    for i, r in enumerate(recs):
        ci, ko, o = ic_held[r.group]
        v, k, spm = sl_held.get(r.group, ship_sp)
        cv_dets.append(with_sl(r, ci, ko, v, cad_held[r.group], spm))
        cv_off.append(o)
        cv_scale.append(k / shipped.sl_correction)
    cii, oi = ci_in, o_in
    vi, ki, spi = sl_ins or ship_sp
    ins_dets = [with_sl(r, cii, ko_in, vi, cad_ins, spi) for r in recs]
    ins_scale = [ki / shipped.sl_correction] * len(recs)
    grid_name = "IC_CANDIDATES" if len(candidates) == len(IC_CANDIDATES) else "IC_CANDIDATES_PEAK"
    by_group = {g: {**candidates[ci], "ic_fill_offset_s": ko[0], "ic_walk_end_offset_s": ko[1],
                    "ic_offset_s": o, "cadence_method": cad_held[g]}
                for g, (ci, ko, o) in ic_held.items()}
    return {
        "shipped_defaults": {**blocks(recs, ship_dets),
                             "ic_detector": _detector_name(shipped),
                             "params": {k: getattr(shipped, k) for k in (*IC_FIELDS,
                                                                          "sl_correction",
                                                                          "sl_hampel_half_width",
                                                                          "bout_average", "sl_turn_per_rad",
                                                                          "bout_strides", "sl_max_tilt_deg",
                                                                          "speed_method")}},
        "cross_validated": {**blocks(recs, cv_dets, offsets=cv_off, sl_scales=cv_scale),
                            "scheme": f"IC constants (ic_method and its constants, {len(candidates)} candidates of "
                                      f"{grid_name}, x ic_offset_s): "
                                      "leave-one-group-out (then, given the fold's detector candidate, the per-kind "
                                      "offsets ic_fill_offset_s x ic_walk_end_offset_s, GRID_KIND_OFFSETS, jointly "
                                      "with ic_offset_s on the same training groups; then cadence_method, "
                                      "median/count/step_mean/per_second/stride_mean, on the cadence MAPE of the fold's IC "
                                      "choice, same folds) "
                                      "over the Voisard subjects + the Mobilise-D participant as one more group; "
                                      "sl_turn_per_rad (stride level), then sl_hampel_half_width, "
                                      "bout_average, bout_strides, sl_correction: leave-one-group-out over "
                                      "the same groups against the spatial references (Voisard: foot INS; "
                                      "Mobilise-D: INDIP), loss = mean of the groups' per-bout stride-length MAE; "
                                      "then speed_method on the groups' per-bout speed MAE",
                            "held_out_choice_by_group": by_group, "sl_held_out_by_group": {
                                g: {"sl_hampel_half_width": v[0], "bout_average": v[1], "sl_turn_per_rad": v[2],
                                    "bout_strides": v[3], "sl_max_tilt_deg": v[4], "sl_correction": k,
                                    "speed_method": m}
                                for g, (v, k, m) in sl_held.items()},
                            **({"note": "only one group: nothing could be held out, this block is in-sample"}
                               if len(set(groups)) < 2 else {})},
        "in_sample": {**blocks(recs, ins_dets, offsets=[oi] * len(recs), sl_scales=ins_scale),
                      "marked": "in-sample: constants chosen on all the recordings scored here",
                      "choice": {**candidates[cii], "ic_fill_offset_s": ko_in[0],
                                 "ic_walk_end_offset_s": ko_in[1], "ic_offset_s": oi, "cadence_method": cad_ins,
                                 "sl_correction": ki, "sl_hampel_half_width": vi[0], "bout_average": vi[1],
                                 "sl_turn_per_rad": vi[2], "bout_strides": vi[3], "sl_max_tilt_deg": vi[4],
                                 "speed_method": spi}},
        "ic_grid_in_sample": {"marked": "in-sample: every IC candidate at its best offset, group-mean loss over all "
                                        "groups (the loss of the leave-one-group-out), overall figures",
                              "candidates": sorted(grid_table, key=lambda x: x["loss_ms"])},
        "_ship_dets": ship_dets,
        "sensor_height_check": sensor_height_check(recs, shipped),
        "turn_check": turn_check(recs, shipped),
        "tilt_gate_check": tilt_gate_check(recs, shipped),
        "ic_misses_by_context": {"shipped_defaults": ic_context(recs, ship_dets),
                                 "cross_validated": ic_context(recs, cv_dets, cv_off)},
        "cadence_by_reference_bout": {"shipped_defaults": cadence_by_reference_bout(recs, ship_dets, shipped),
                                      "note": "Mobilise-D, shipped defaults: per INDIP bout the matched bout of ours "
                                              "and our contacts' cadence inside the reference bout"},
        "ic_timing_by_kind": {"shipped_defaults": ic_timing_by_kind(recs, ship_dets),
                              "cross_validated": ic_timing_by_kind(recs, cv_dets, cv_off),
                              "note": "matched contacts by how they were found (estimators/trunk_gait/_icd.IC_KINDS; "
                                      "peak_before_closing = the threshold peak right before a closing step); "
                                      "share_of_timing_mae_ms = the kind's sum of |error| / all matched contacts"},
        "ic_kind_offsets_in_sample": {"marked": "in-sample: the in-sample detector candidate with each "
                                                "(ic_fill_offset_s, ic_walk_end_offset_s) of GRID_KIND_OFFSETS at its "
                                                "best ic_offset_s, group-mean loss over all groups",
                                      "candidates": sorted(kind_table, key=lambda x: x["loss_ms"])},
    }


# ---------------------------------------------------------------------------------------------------- mobgap

def mobgap_inputs(recs: list[Rec], measured_sensor_height: bool = True) -> tuple[list[str], dict]:
    """(input names, arrays) for the mobgap runner: per recording an "as worn" and an "aligned" variant.
    ``measured_sensor_height``: mobgap's pendulum length = the recording's measured sensor height where it has one
    (mobgap's own use), else 0.53 x height (as its MsProject loader; False = 0.53 x height everywhere, the length
    StrideLab's sl_correction is calibrated with)."""
    from stridelab.estimators.trunk_gait import detect_trunk_frame
    arrays = {}
    names = []
    for i, r in enumerate(recs):
        key = f"r{i}"
        names.append(key)
        sensor_h = r.sensor_height_m if (measured_sensor_height and r.sensor_height_m) else 0.53 * (r.height_m or 1.70)
        meta = np.array([r.fs, r.height_m or 1.70, sensor_h])
        # as worn: the device's fixed axis mapping to mobgap's x up / z forward
        arrays[f"as_worn_{key}/acc"] = r.acc @ r.mobgap_axes.T
        arrays[f"as_worn_{key}/gyr"] = np.rad2deg(r.gyr @ r.mobgap_axes.T)
        arrays[f"as_worn_{key}/meta"] = meta
        # aligned: our detected frame (x anterior, y up, z right) -> mobgap (x up, y right, z anterior)
        R = detect_trunk_frame(r.acc, r.gyr, r.fs).R
        M = np.array([R[1], R[2], R[0]])
        arrays[f"aligned_{key}/acc"] = r.acc @ M.T
        arrays[f"aligned_{key}/gyr"] = np.rad2deg(r.gyr @ M.T)
        arrays[f"aligned_{key}/meta"] = meta
    return names, arrays


def mobgap_cache_path(python: Path, all_names: list[str], arrays: dict) -> Path:
    """Cache file of mobgap's output beside its environment, keyed by the hash of the runner, the environment's
    pinned requirements and the inputs (a rerun of the bench then costs seconds, not minutes)."""
    h = hashlib.sha256(MOBGAP_RUNNER.read_bytes() + MOBGAP_REQUIREMENTS.read_bytes())
    for n in all_names:
        for part in ("acc", "gyr", "meta"):
            h.update(np.ascontiguousarray(arrays[f"{n}/{part}"]).tobytes())
    return python.absolute().parent.parent / "stridelab-cache" / f"mobgap-{h.hexdigest()[:24]}.json"


def run_mobgap(recs: list[Rec], python: Path, show: bool,
               measured_sensor_height: bool = True) -> tuple[dict | None, str | None]:
    """{variant: {pipeline: [Det | None per recording]}} from mobgap, or (None, reason)."""
    if not python.is_file():
        return None, (f"mobgap environment not found at {python}: run `make .venv-mobgap` (isolated venv with "
                      "mobgap==1.2.0, validation/anchors/mobgap-requirements.txt)")
    variants = ("as_worn", "aligned")
    names, arrays = mobgap_inputs(recs, measured_sensor_height)
    all_names = [f"{v}_{k}" for v in variants for k in names]
    cache = mobgap_cache_path(python, all_names, arrays)
    if cache.is_file():
        out = json.loads(cache.read_text())
        if show:
            _say(f"mobgap results from the cache {cache}")
    else:
        with tempfile.TemporaryDirectory(prefix="stridelab-mobgap-") as td:
            src, dst = Path(td) / "in.npz", Path(td) / "out.json"
            np.savez(src, names=np.array(all_names), **arrays)
            if show:
                _say(f"running mobgap on {len(all_names)} inputs x 2 pipelines in {python} …")
            env = {**os.environ, "PYTHONWARNINGS": "ignore"}
            try:
                proc = subprocess.run([str(python), str(MOBGAP_RUNNER), str(src), str(dst)], env=env,
                                      stdout=subprocess.PIPE, stderr=None if show else subprocess.DEVNULL, text=True,
                                      timeout=3600)
            except (OSError, subprocess.TimeoutExpired) as e:
                return None, f"mobgap runner failed to run: {e}"
            if proc.returncode != 0 or not dst.is_file():
                return None, f"mobgap runner exited with {proc.returncode}"
            out = json.loads(dst.read_text())
        try:
            cache.parent.mkdir(parents=True, exist_ok=True)
            cache.write_text(json.dumps(out))
        except OSError:
            pass
    res: dict = {"_version": out.get("_mobgap_version")}
    for v in variants:
        res[v] = {}
        for pipe in ("healthy", "impaired"):
            lst = []
            for k in names:
                o = out.get(f"{v}_{k}", {}).get(pipe, {"error": "missing"})
                if "error" in o:
                    lst.append(Det(ic_s=np.empty(0), bouts={k2: np.empty(0) for k2 in (
                        "start_s", "end_s", "cadence_spm", "stride_length_m", "walking_speed_m_s")}))
                    continue
                f = lambda x: np.array([np.nan if y is None else y for y in x], float)  # noqa: E731
                lst.append(Det(ic_s=np.asarray(o["ic_s"], float),
                               bouts={"start_s": f(o["wb_start_s"]), "end_s": f(o["wb_end_s"]),
                                      "cadence_spm": f(o["cadence_spm"]), "stride_length_m": f(o["stride_length_m"]),
                                      "walking_speed_m_s": f(o["walking_speed_m_s"])}))
            res[v][pipe] = lst
        res.setdefault("_errors", []).extend(
            f"{recs[int(k[1:])].name} {v} {p}: {out[f'{v}_{k}'][p]['error']}" for k in names
            for p in ("healthy", "impaired") if "error" in out.get(f"{v}_{k}", {}).get(p, {}))
    return res, None


def with_leg_length(recs: list[Rec], mg: dict, python: Path, show: bool) -> dict:
    """``mg`` with the recordings that have a measured sensor height rerun with mobgap's pendulum length = 0.53 x
    height, the length StrideLab's pendulum uses and both tools' factors are tuned with (a factor tuned on
    0.53 x height does not carry over to a measured sensor height: ``sensor_height_check``). Unchanged when there is
    no such recording or that run fails (said in ``_errors``)."""
    idx = [i for i, r in enumerate(recs) if r.sensor_height_m]
    if not idx:
        return mg
    sub, reason = run_mobgap([recs[i] for i in idx], python, show, measured_sensor_height=False)
    if sub is None:
        return {**mg, "_errors": mg.get("_errors", []) + [f"leg-length rerun: {reason}"]}
    out = {**mg, "_errors": mg.get("_errors", []) + sub.get("_errors", [])}
    for v in ("as_worn", "aligned"):
        out[v] = {}
        for p in ("healthy", "impaired"):
            lst = list(mg[v][p])
            for j, i in enumerate(idx):
                lst[i] = sub[v][p][j]
            out[v][p] = lst
    return out


def anchor_block(recs: list[Rec], mg: dict, mg_tuned: dict | None = None) -> dict:
    """mobgap as shipped (both pipelines, as worn, measured sensor height) and tuned with the same LOGO (pipeline x
    frame x offset, then its stride-length factor) on ``mg_tuned`` (the runs with the pendulum length StrideLab
    uses, ``with_leg_length``; ``mg`` when None)."""
    out = {"tool": f"mobgap {mg.get('_version')}", "errors": (mg_tuned or mg).get("_errors", [])}
    for v in ("as_worn", "aligned"):
        for p in ("healthy", "impaired"):
            out[f"{p}_{v}"] = blocks(recs, mg[v][p])
    shipped_mg = mg
    mg = mg_tuned or mg
    cands = [(v, p, o) for v in ("as_worn", "aligned") for p in ("healthy", "impaired") for o in GRID_OFFSET_S]
    cache: dict = {}

    def group_loss(g, c):
        if (g, c) not in cache:
            v, p, o = cands[c]
            idx = [i for i, r in enumerate(recs) if r.group == g]
            cache[(g, c)] = ic_loss(ic_score([recs[i] for i in idx], [mg[v][p][i] for i in idx], offset_s=o))
        return cache[(g, c)]
    logo = _logo([r.group for r in recs], lambda gs, c: float(np.mean([group_loss(g, c) for g in gs])), len(cands))
    groups = sorted({r.group for r in recs})

    def sl_scale_on(train: list[str], v: str, p: str) -> float:
        """mobgap's stride-length factor (as a multiple of its shipped 4.587/4; its stride length and speed are
        linear in it) chosen like ours: mean over the training groups of their per-bout stride-length MAE."""
        def loss(k):
            x = [sl_mae([r for r in recs if r.group == g], [mg[v][p][i] for i, r in enumerate(recs) if r.group == g],
                        k) for g in train]
            x = [y for y in x if np.isfinite(y)]
            return float(np.mean(x)) if x else float("inf")
        losses = [loss(k) for k in GRID_MOBGAP_SL]
        return float(GRID_MOBGAP_SL[int(np.argmin(losses))]) if np.isfinite(min(losses)) else 1.0
    held_scale = {}
    for g in groups:
        v, p, _o = cands[logo["held_out_choice"][g]]
        held_scale[g] = sl_scale_on([x for x in groups if x != g] or [g], v, p)
    dets, offs, scales = [], [], []
    for i, r in enumerate(recs):
        v, p, o = cands[logo["held_out_choice"][r.group]]
        dets.append(mg[v][p][i])
        offs.append(o)
        scales.append(held_scale[r.group])
    out["cross_validated"] = {**blocks(recs, dets, offsets=offs, sl_scales=scales),
                              "scheme": "same leave-one-group-out and loss as StrideLab's IC constants over "
                                        "pipeline (healthy/impaired) x input frame (as_worn/aligned) x IC offset; "
                                        "then mobgap's stride-length factor (x 0.80..1.40 of its shipped value) "
                                        "by the same leave-one-group-out and loss as StrideLab's sl_correction, "
                                        "with the pendulum length StrideLab uses (0.53 x height) everywhere",
                              "held_out_choice_by_group": {g: {**dict(zip(("frame", "pipeline", "ic_offset_s"),
                                                                          cands[c])),
                                                               "stride_length_factor": held_scale[g]}
                                                           for g, c in logo["held_out_choice"].items()}}
    v, p, o = cands[logo["in_sample_choice"]]
    k_in = sl_scale_on(groups, v, p)
    out["in_sample"] = {**blocks(recs, mg[v][p], offsets=[o] * len(recs), sl_scales=[k_in] * len(recs)),
                        "marked": "in-sample", "choice": {"frame": v, "pipeline": p, "ic_offset_s": o,
                                                          "stride_length_factor": k_in}}
    out["shipped_defaults"] = {**blocks(recs, shipped_mg["as_worn"]["healthy"]),
                               "note": "MobilisedPipelineHealthy as shipped (the pipeline mobgap recommends for "
                                       "healthy adults, as both data sets are), input as worn, pendulum length = "
                                       "the measured sensor height where known (Mobilise-D), else 0.53 x height"}
    return out


def gaps(res: dict) -> dict:
    """StrideLab minus mobgap per key, data set and block (shipped vs shipped, cross-validated vs cross-validated);
    positive is better for StrideLab on sensitivity and precision, negative is better on the error keys."""
    a = res.get("anchor")
    if not a:
        return {}
    out = {}
    for blk in ("shipped_defaults", "cross_validated"):
        out[blk] = {}
        for ds in ("voisard", "mobilised", "overall"):
            if ds in res[blk] and ds in a[blk]:
                out[blk][ds] = {k: (None if res[blk][ds][k] is None or a[blk][ds][k] is None
                                    else round(res[blk][ds][k] - a[blk][ds][k], 4)) for k in KEYS}
    return out


def foot_reference_summary(recs: list[Rec]) -> dict:
    """How well the two feet of one Voisard trial agree on the mean stride length (a floor for the foot-INS
    reference's own error), and the reference's range."""
    rows = [r.foot_reference for r in recs if r.dataset == "voisard" and r.foot_reference]
    if not rows:
        return {"trials": 0}
    lr = np.array([abs(x["left"] - x["right"]) for x in rows if np.isfinite(x["left"]) and np.isfinite(x["right"])])
    mean_lr = np.array([(x["left"] + x["right"]) / 2 for x in rows
                        if np.isfinite(x["left"]) and np.isfinite(x["right"])])
    sl = np.array([r.ref_bouts["stride_length_m"][0] for r in recs if r.dataset == "voisard"], float)
    return {"trials": len(rows), "strides": int(sum(x["n_strides"] for x in rows)),
            "left_right_abs_diff_m_median": round(float(np.median(lr)), 4) if len(lr) else None,
            "left_right_abs_diff_pct_median": round(float(np.median(100 * lr / mean_lr)), 2) if len(lr) else None,
            "stride_length_m_range": [round(float(np.nanmin(sl)), 3), round(float(np.nanmax(sl)), 3)]}


# ------------------------------------------------------------------------------------------------------- speed

def day_speed(recs: list[Rec]) -> dict:
    """CPU seconds of analyse_trunk_gait + daily_outcomes on a synthetic 24 h lower-back day at 100 Hz."""
    from stridelab.estimators.trunk_gait import analyse_trunk_gait, daily_outcomes
    fs = 100.0
    src = [r for r in recs if r.dataset == "mobilised" and abs(r.fs - fs) < 1e-6] or \
          [r for r in recs if abs(r.fs - fs) < 1e-6]
    if not src:
        return {"skipped": "no 100 Hz recording to build the day from"}
    rng = np.random.default_rng(0)
    n = int(24 * 3600 * fs)
    acc = np.empty((n, 3))
    gyr = np.empty((n, 3))
    period = int(15 * 60 * fs)
    inserted = 0
    walking_src_s = 0.0
    for k, s in enumerate(range(0, n, period)):
        e = min(s + period, n)
        # still: a posture (sensor tilt) per period, sensor noise
        tilt = rng.uniform(-1.2, 1.2)
        g = 9.81 * np.array([np.cos(tilt), 0.0, np.sin(tilt)])
        acc[s:e] = g + rng.normal(0, 0.02, (e - s, 3))
        gyr[s:e] = rng.normal(0, 0.003, (e - s, 3))
        r = src[k % len(src)]
        m = min(len(r.acc), e - s)
        acc[s:s + m] = r.acc[:m] @ r.mobgap_axes.T if r.dataset == "voisard" else r.acc[:m]
        gyr[s:s + m] = r.gyr[:m] @ r.mobgap_axes.T if r.dataset == "voisard" else r.gyr[:m]
        inserted += 1
        walking_src_s += m / fs
    from stridelab.estimators.trunk_gait import TrunkGaitParams
    analyse_trunk_gait(acc[: int(600 * fs)], gyr[: int(600 * fs)], fs, params=TrunkGaitParams())   # warm-up
    t0 = time.process_time()
    w0 = time.perf_counter()
    res = analyse_trunk_gait(acc, gyr, fs)
    b = res.bouts
    daily_outcomes(b.start_s, b.duration_s, b.cadence_spm, b.stride_length_m, b.walking_speed_m_s,
                   res.strides.speed_m_s, stride_bout=res.strides.bout)
    cpu = time.process_time() - t0
    return {"cpu_s": round(cpu, 3), "wall_s": round(time.perf_counter() - w0, 3), "target_cpu_s": 2.0,
            "samples": n, "fs_hz": fs, "recordings_inserted": inserted,
            "recording_time_inserted_s": round(walking_src_s),
            "bouts_found": len(b), "walking_time_s": round(float(b.duration_s.sum()), 1),
            "composition": "24 h at 100 Hz: still periods (posture tilt, noise) with one real lower-back recording "
                           f"({', '.join(sorted({r.name for r in src}))}) inserted every 15 min"}


# ---------------------------------------------------------------------------------------------------- command

def run_benchmark(voisard: Path | None, mobilised: Path | None, *, mobgap_python: Path, anchor: bool = True,
                  day: bool = True, limit: int | None = None, show: bool = True,
                  all_ic_methods: bool = False) -> dict:
    failed: list[dict] = []
    recs: list[Rec] = []
    if voisard is not None:
        if not voisard.is_dir():
            raise UserError(f"{voisard}: not a folder; expected the Voisard et al. gait data (N-M.json, N-M_lb.txt)")
        recs += load_voisard(voisard, failed, limit)
    if mobilised is not None:
        recs += load_mobilised(mobilised, failed)
    if not recs:
        raise UserError("no recording could be read; see the skipped files above")
    if show:
        _say(f"{len(recs)} recordings ({len(failed)} skipped); running the IC grid …")
    res = tune_and_score(recs, show, IC_CANDIDATES if all_ic_methods else IC_CANDIDATES_PEAK)
    res.pop("_ship_dets")
    if anchor:
        mg, reason = run_mobgap(recs, mobgap_python, show)
        res["anchor"] = (anchor_block(recs, mg, with_leg_length(recs, mg, mobgap_python, show))
                         if mg is not None else None)
        if mg is None:
            res["anchor_reason"] = reason
        else:
            res["gap_vs_anchor"] = gaps(res)
    else:
        res["anchor"] = None
        res["anchor_reason"] = "--no-anchor given"
    if day:
        if show:
            _say("measuring the 24 h day …")
        res["speed_day"] = day_speed(recs)
    res["constants"] = [
        {"name": "TrunkGaitParams.ic_method / ic_offset_s / ic_smooth_s / ic_prominence / ic_fill_prominence / "
                 "ic_fill_edge_steps / ic_fill_end_steps / ic_zc_sigma_s / ic_zc_min_depth / cadence_method",
         "grid": ("IC_CANDIDATES (--all-ic-methods)" if all_ic_methods else "IC_CANDIDATES_PEAK (default; the other "
                  "detectors with --all-ic-methods)") + " x GRID_OFFSET_S of validation/bench/trunk_gait.py",
         "chosen_on": "Voisard subjects + Mobilise-D HA-001 (leave-one-group-out for the cross-validated figure)"},
        {"name": "TrunkGaitParams.sl_correction / sl_hampel_half_width / bout_average / bout_strides / "
                 "sl_turn_per_rad / speed_method",
         "chosen_on": "Voisard subjects (foot-INS stride length) + Mobilise-D HA-001 (INDIP stride length), "
                      "leave-one-group-out for the cross-validated figure"}]
    res["spatial_references"] = {
        "voisard": "derived: mean stride length / speed of both foot MTws by StrideLab's foot INS (stridelab.estimators.gait."
                   "foot_kinematics, stride length MAE 1.6-1.9 cm vs optical markers on the gaitmap walk, docs/gait.md)"
                   "; strides heel strike to heel strike inside TrialBoundaries, U-turn included",
        "mobilised": "INDIP MicroWB AverageStrideLength / WalkingSpeed"}
    res["voisard_foot_reference"] = foot_reference_summary(recs)
    res["failed_files"] = failed
    res["recordings"] = {"voisard": sum(r.dataset == "voisard" for r in recs),
                         "mobilised": sum(r.dataset == "mobilised" for r in recs)}
    res["keys"] = list(KEYS)
    return res


@click.command("trunk-gait")
@click.option("--voisard", type=click.Path(path_type=Path), default=None,
              help="Voisard et al. 2023 folder (N-M.json + N-M_lb.txt); default ../shared/data/voisard_gait if present")
@click.option("--mobilised", type=click.Path(path_type=Path), default=None,
              help="Mobilise-D standardized data folder (…/<cohort>/<id>/data.mat) or one data.mat")
@click.option("--mobgap-python", type=click.Path(path_type=Path), default=DEFAULT_MOBGAP_PY, show_default=True,
              help="interpreter of the isolated mobgap environment (make .venv-mobgap)")
@click.option("--no-anchor", is_flag=True, help="skip mobgap")
@click.option("--day/--no-day", default=True, show_default=True, help="measure the 24 h day's CPU seconds")
@click.option("--limit", type=int, default=None, help="only the first N Voisard trials (development)")
@click.option("--all-ic-methods", is_flag=True,
              help="also score the ionescu / shin / hklee detectors in the IC grid (never chosen; slower)")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(voisard: Path | None, mobilised: Path | None, mobgap_python: Path, no_anchor: bool, day: bool,
            limit: int | None, all_ic_methods: bool, as_json: bool) -> None:
    """Trunk gait (initial contacts, bouts, cadence, stride length, speed) against Voisard and Mobilise-D references,
    with mobgap as the anchor.

    \b
    Examples:
      stridelab bench trunk-gait --voisard ../shared/data/voisard_gait --mobilised ../shared/data/mobilised_lab --json
      stridelab bench trunk-gait --voisard ../shared/data/voisard_gait --no-anchor --no-day --limit 12
    """
    if voisard is None and mobilised is None:
        if DEFAULT_VOISARD.is_dir():
            voisard = DEFAULT_VOISARD
        else:
            raise UserError("give --voisard DIR and/or --mobilised DIR (public data, see DESIGN.md 'Real data')")
    res = run_benchmark(voisard, mobilised, mobgap_python=mobgap_python, anchor=not no_anchor, day=day,
                        limit=limit, show=True, all_ic_methods=all_ic_methods)
    if as_json:
        emit_json(res)
    else:
        for blk in ("shipped_defaults", "cross_validated", "in_sample"):
            click.echo(f"{blk}: " + json.dumps({k: res[blk]["overall"].get(k) for k in KEYS}))
        if res.get("anchor"):
            click.echo("anchor (cross-validated): " + json.dumps({k: res["anchor"]["cross_validated"]["overall"]
                                                                  .get(k) for k in KEYS}))
        else:
            click.echo(f"anchor: null ({res.get('anchor_reason')})")
        if "speed_day" in res:
            click.echo(f"speed_day: {res['speed_day']}")
        for f in res["failed_files"]:
            click.echo(f"failed: {f['file']}: {f['reason']}")


if __name__ == "__main__":  # pragma: no cover
    command(sys.argv[1:])
