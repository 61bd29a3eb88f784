"""Walking bouts and daily gait outcomes from one trunk sensor (``lower_back`` or ``chest``): warehouse ->
stridelab.estimators.trunk_gait -> warehouse, the first stage in the shape of :mod:`stridelab.pipeline.stages._shape`.

``compute``: per recording the first trunk placement it carries (lower_back before chest) is read, cut into local
calendar days when longer than ``day_pieces_above_s``, and handed to
:func:`stridelab.estimators.trunk_gait.analyse_trunk_gait` with the session's ``height_m`` / ``leg_length_m`` (documented
defaults when unknown: the bouts say so in ``height_source`` and the ``default_height`` flag). The warnings of the
sensor frame the estimators detect from the data (:func:`stridelab.estimators.trunk_gait.detect_trunk_frame`) become flags on
every bout of that piece (:data:`FRAME_FLAGS`: ``wrong_placement`` when no stable vertical axis is found,
``upside_down`` (corrected), ``anterior_uncertain``) and go into the run's note. On free-living sessions the bouts of each local day give one
``daily_gait_outcomes`` row (:func:`stridelab.estimators.trunk_gait.daily_outcomes`).

``score`` (separate step): where the session holds reference walking bouts and initial contacts (Mobilise-D INDIP
annotations, ``label`` = ``reference_system``), initial contacts and per-bout cadence, stride length and walking
speed are scored by the one scorer :mod:`stridelab.estimators.trunk_gait.evaluation` into ``accuracy_metrics`` /
``accuracy_pairs`` (the dashboard's Accuracy page); contacts inside the reference walking bouts ± the tolerance, as
``stridelab bench trunk-gait`` scores them (the whole recording where the reference has contacts but no bouts).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from stridelab.estimators.recording import TRUNK_PLACEMENTS
from stridelab.pipeline.stages._shape import StageContext, shaped_stage

if TYPE_CHECKING:
    from stridelab.estimators.trunk_gait import TrunkGaitParams


def _estimator_defaults() -> "TrunkGaitParams":
    # imported when the parameters are made, not with the registry: stridelab.estimators.trunk_gait brings SciPy's signal
    # package, which the coordinator and every worker would otherwise import for every stage
    from stridelab.estimators.trunk_gait import TrunkGaitParams
    return TrunkGaitParams()

TABLES = ("walking_bouts", "daily_gait_outcomes", "accuracy_metrics", "accuracy_pairs")
ESTIMATOR = "trunk_gait"
#: detected-frame warning (its opening words) -> bout quality flag
FRAME_FLAGS = {"vertical axis not found": "wrong_placement", "sensor looks upside down": "upside_down",
               "anterior axis uncertain": "anterior_uncertain"}


@dataclass(frozen=True)
class TrunkGaitStageParams:
    """placements: trunk placements read, in order of preference (first one a recording carries).
    day_pieces_above_s: recordings longer than this (s) are analysed one local calendar day at a time (a bout
      crossing midnight is then cut in two).
    reference_system: the reference the score step reads (annotation label, e.g. INDIP).
    ic_tolerance_s: initial contacts further apart than this (s) do not match (the scorer's default).
    bout_min_iou: walking bouts match when their intersection over union reaches this.
    estimator: the trunk-gait estimator parameters (shipped defaults)."""
    placements: tuple[str, ...] = TRUNK_PLACEMENTS
    day_pieces_above_s: float = 26 * 3600.0
    reference_system: str = "INDIP"
    ic_tolerance_s: float = 0.25
    bout_min_iou: float = 0.5
    estimator: "TrunkGaitParams" = field(default_factory=_estimator_defaults)


def _num(x) -> float | None:
    return float(x) if x is not None and np.isfinite(x) else None


def _body(rec: dict, key: str) -> float | None:
    v = rec.get("metadata", {}).get(key)
    try:
        return float(v) if v not in (None, "") else None
    except (TypeError, ValueError):
        return None


def _pieces(t_ns: np.ndarray, tz: str) -> list[tuple[int, int]]:
    """[start, stop) rows of each local calendar day touched by the stamps ``t_ns``."""
    from stridelab.estimators.activity._daily import local_midnights_ns
    cuts = [int(np.searchsorted(t_ns, b)) for _, _, b in local_midnights_ns(int(t_ns[0]), int(t_ns[-1]), tz)[:-1]]
    edges = [0] + [c for c in cuts if 0 < c < len(t_ns)] + [len(t_ns)]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def compute(ctx: StageContext, p: TrunkGaitStageParams) -> None:
    from stridelab.estimators.trunk_gait import analyse_trunk_gait, daily_outcomes
    tz = ctx.session.get("timezone") or "UTC"
    free_living = ctx.session.get("kind") == "free_living"
    for desc in ctx.imus(read=False):
        rec = desc.recording
        long = desc.n_samples / desc.fs_hz > p.day_pieces_above_s
        day_bouts: dict[str, list] = {}
        for a, b in (_pieces(ctx.read_times(desc), tz) if long else [(0, desc.n_samples)]):
            imu = ctx.read_imu(desc, a, b)                       # one local day at a time when long
            if imu.gyr is None:
                ctx.note(f"{rec.get('trial')}: {imu.placement} has no gyroscope (trunk gait needs one)")
                break
            t = imu.t_ns
            res = analyse_trunk_gait(imu.acc, imu.gyr, imu.fs_hz, placement=imu.placement,
                                     height_m=_body(rec, "height_m"), leg_length_m=_body(rec, "leg_length_m"),
                                     params=p.estimator)
            del imu
            ctx.found.append((rec, desc.placement, t, res))    # for the score step
            frame_flags = sorted({f for w in res.frame.warnings for k, f in FRAME_FLAGS.items() if w.startswith(k)})
            for w in dict.fromkeys(res.warnings + res.frame.warnings):
                ctx.note(f"{rec.get('trial')}: {desc.placement}: {w}")
            t0 = int(t[0])
            rows = []
            for bt in res.bouts.records():
                flags = list(bt["flags"]) + frame_flags
                rows.append({"session_id": ctx.session_id, "content_hash": rec["content_hash"],
                             "placement": desc.placement, "start_ns": t0 + int(round(bt["start_s"] * 1e9)),
                             "end_ns": t0 + int(round(bt["end_s"] * 1e9)), "duration_s": bt["duration_s"],
                             "n_steps": bt["n_steps"], "n_strides": bt["n_strides"],
                             "cadence_spm": _num(bt["cadence_spm"]), "stride_length_m": _num(bt["stride_length_m"]),
                             "walking_speed_m_s": _num(bt["walking_speed_m_s"]), "n_turns": bt["n_turns"],
                             "flags": ",".join(sorted(set(flags))), "frame_confidence": float(res.frame.confidence),
                             "height_source": res.height_source})
            ctx.emit("walking_bouts", rows)
            if free_living:
                _days(day_bouts, res, t, desc.fs_hz, tz)
        for date, parts in sorted(day_bouts.items()):
            ctx.emit("daily_gait_outcomes", [_day_row(ctx, date, desc.placement, parts, daily_outcomes)])


def _days(day_bouts: dict, res, t: np.ndarray, fs: float, tz: str) -> None:
    """Split one analysed piece into local days: per day the bouts (by their start) and strides, and the
    seconds of that day the piece covers."""
    from stridelab.estimators.activity._daily import local_midnights_ns
    t0 = int(t[0])
    bs = t0 + np.round(res.bouts.start_s * 1e9).astype(np.int64)
    for date, lo, hi in local_midnights_ns(int(t[0]), int(t[-1]), tz):
        sel = (bs >= lo) & (bs < hi)
        covered = float(np.count_nonzero((t >= lo) & (t < hi))) / fs
        idx = np.flatnonzero(sel)
        remap = -np.ones(len(bs), np.int64)
        remap[idx] = np.arange(len(idx))
        sb = res.strides.bout
        keep = sel[sb] if len(sb) else np.zeros(0, bool)
        day_bouts.setdefault(date, []).append({
            "start": res.bouts.start_s[idx], "dur": res.bouts.duration_s[idx], "cad": res.bouts.cadence_spm[idx],
            "sl": res.bouts.stride_length_m[idx], "sp": res.bouts.walking_speed_m_s[idx],
            "stride_speed": res.strides.speed_m_s[keep], "stride_bout": remap[sb[keep]],
            "recorded_s": covered, "height_source": res.height_source})


def _day_row(ctx: StageContext, date: str, placement: str, parts: list[dict], daily_outcomes) -> dict:
    cat = lambda k: np.concatenate([x[k] for x in parts]) if parts else np.zeros(0)  # noqa: E731
    offs = np.cumsum([0] + [len(x["start"]) for x in parts[:-1]])
    sb = np.concatenate([x["stride_bout"] + o for x, o in zip(parts, offs)]) if parts else np.zeros(0, np.int64)
    d = daily_outcomes(cat("start"), cat("dur"), cat("cad"), cat("sl"), cat("sp"), cat("stride_speed"),
                       stride_bout=sb)
    c = d.n_bouts_by_class
    return {"session_id": ctx.session_id, "date": date, "placement": placement,
            "recorded_s": float(sum(x["recorded_s"] for x in parts)), "walking_time_s": float(d.walking_time_s),
            "n_bouts": int(d.n_bouts), "n_bouts_10_30s": int(c[0]), "n_bouts_30_60s": int(c[1]),
            "n_bouts_60_120s": int(c[2]), "n_bouts_over_120s": int(c[3]), "n_bouts_over_10s": int(d.n_bouts_over_10s),
            "speed_median_m_s": _num(d.speed_median_m_s), "speed_p95_m_s": _num(d.speed_p95_m_s),
            "stride_length_median_m": _num(d.stride_length_median_m),
            "stride_length_p95_m": _num(d.stride_length_p95_m), "cadence_median_spm": _num(d.cadence_median_spm),
            "cadence_p95_spm": _num(d.cadence_p95_spm), "stride_velocity_p95_m_s": _num(d.stride_velocity_p95_m_s),
            "height_source": parts[0]["height_source"]}


def score(ctx: StageContext, p: TrunkGaitStageParams) -> None:
    """Initial contacts and per-bout parameters against the session's reference (``reference_system``), pooled
    over the session's recordings, with the one scorer (``stridelab.estimators.trunk_gait.evaluation``)."""
    from stridelab.estimators.trunk_gait.evaluation import (bout_errors, ic_metrics, match_bouts, match_initial_contacts,
                                                  summarise_bout_errors)
    tp = fp = fn = 0
    errs, abs_err, pairs, placements = [], [], [], set()
    for rec, placement, t, res in ctx.found:
        ref_b = ctx.events("walking_bout", p.reference_system, rec)
        ref_ic = ctx.events("IC", p.reference_system, rec)
        if not ref_b and not ref_ic:
            continue
        placements.add(placement)
        t0 = int(t[0])
        s = lambda ns: (np.asarray(ns, np.int64) - t0) / 1e9   # noqa: E731 - warehouse ns -> s from the piece start
        ric = np.sort(s([e["t_ns"] for e in ref_ic if t[0] <= e["t_ns"] <= t[-1]]))
        rb = [e for e in ref_b if e.get("end_ns") is not None and t[0] <= e["t_ns"] <= t[-1]]
        # contacts scored inside the reference walking bouts ± the tolerance, as the bench scores them
        win = np.column_stack([s([e["t_ns"] for e in rb]), s([e["end_ns"] for e in rb])]) if rb else None
        m = match_initial_contacts(res.initial_contacts_s, ric, tolerance_s=p.ic_tolerance_s, windows_s=win)
        mm = ic_metrics(m)
        tp, fp, fn = tp + mm["tp"], fp + mm["fp"], fn + mm["fn"]
        abs_err.append(np.abs(m.error_s))
        pairs += [{"quantity": "IC", "estimate": float(res.initial_contacts_s[i]), "reference": float(ric[j]),
                   "unit": "s", "placement": placement} for i, j in zip(m.det_idx, m.ref_idx)]
        ref = {k: np.array([np.nan if e.get(k) is None else float(e[k]) for e in rb])
               for k in ("cadence_spm", "stride_length_m", "walking_speed_m_s")}
        det = {"cadence_spm": res.bouts.cadence_spm, "stride_length_m": res.bouts.stride_length_m,
               "walking_speed_m_s": res.bouts.walking_speed_m_s}
        bm = match_bouts(res.bouts.start_s, res.bouts.end_s, s([e["t_ns"] for e in rb]), s([e["end_ns"] for e in rb]),
                         min_iou=p.bout_min_iou)
        e = bout_errors(bm, det, ref)
        errs.append(e)
        for k, unit in (("walking_speed_m_s", "m/s"), ("stride_length_m", "m"), ("cadence_spm", "steps/min")):
            pairs += [{"quantity": k, "estimate": float(det[k][i]), "reference": float(ref[k][j]), "unit": unit,
                       "placement": placement} for i, j in zip(bm.det_idx, bm.ref_idx)
                      if np.isfinite(det[k][i]) and np.isfinite(ref[k][j])]
        pairs += [{"quantity": "bout_iou", "estimate": float(x), "reference": 1.0, "unit": "fraction",
                   "placement": placement} for x in bm.iou]
    if not placements:
        return
    pl = "/".join(sorted(placements))
    est = f"{ESTIMATOR} vs {p.reference_system}"
    ae = np.concatenate(abs_err) if abs_err else np.zeros(0)
    sb = summarise_bout_errors(errs)
    metrics = {"ic_sensitivity": (tp / (tp + fn) if tp + fn else None, "fraction"),
               "ic_precision": (tp / (tp + fp) if tp + fp else None, "fraction"),
               "ic_timing_mae_ms": (1000 * float(ae.mean()) if ae.size else None, "ms"),
               "cadence_mape_pct": (sb["cadence_mape_pct"], "%"),
               "stride_length_mae_m": (sb["stride_length_mae_m"], "m"),
               "walking_speed_mae_m_s": (sb["walking_speed_mae_m_s"], "m/s"),
               "n_reference_ic": (float(tp + fn), "contacts"), "n_matched_bouts": (float(sb["n_bouts_speed"]), "bouts")}
    ctx.emit("accuracy_metrics", [{"session_id": ctx.session_id, "stage": "trunk_gait", "estimator": est,
                                   "placement": pl, "metric": k, "value": float(v), "unit": u}
                                  for k, (v, u) in metrics.items() if v is not None])
    ctx.emit("accuracy_pairs", [{"session_id": ctx.session_id, "stage": "trunk_gait", "estimator": est, **r}
                                for r in pairs])


# version 6: bout stride length / speed leave out strides over a stop and the speed uses the count cadence (the
# estimator logic changed, not only its defaults, which are in the stamp anyway)
# version 7: per-kind contact offsets (ic_fill_offset_s, ic_walk_end_offset_s): the stored contact times of closing
# steps, gap fills and the last step of each walk move
# version 8: bout cadence "stride_mean" (mean of 120 / stride time over the bout's strides, the INDIP definition):
# the stored per-bout cadence changes
STAGE = shaped_stage("trunk_gait", "8", TrunkGaitStageParams, compute, score=score, placements=TRUNK_PLACEMENTS,
                     tables=TABLES, session_kinds=("lab", "free_living"))
