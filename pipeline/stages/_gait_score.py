"""The score step of the gait stage (:mod:`stridelab.pipeline.stages.gait`): its events, strides and foot trajectories
against the session's references, each by the one scorer of its quantity (the one ``stridelab bench gait`` /
``bench trajectory`` use): events :func:`stridelab.estimators.gait.evaluation.event_accuracy`, stride lengths
:func:`stridelab.estimators.gait.evaluation.stride_length_reference` + :func:`~stridelab.estimators.gait.evaluation.paired_errors`,
trajectories :func:`stridelab.estimators.trajectory.evaluation.armse_2d_aligned` / ``armse_3d_aligned``."""
from __future__ import annotations

import numpy as np

from stridelab.pipeline.stages._gait_rows import SIDES, num

ESTIMATOR = "eskf_zupt_rts+thesis_icd"


def rec_events(events: list[dict], rec: dict, types: tuple[str, ...]) -> list[dict]:
    """The session's reference annotations of these types that start inside the recording."""
    return [e for e in events if e["type"] in types and rec["start_ns"] <= e["t_ns"] <= rec["end_ns"]]


def annotated_span(events: list[dict], rec: dict, placement: str) -> tuple[int, int] | None:
    """(lo, hi) ns of the part of the recording the reference annotates for this foot: the hull of its ``score``
    spans (Voisard's TrialBoundaries) and ``annotated`` spans (gaitmap's labelled strides); None when it marks none."""
    sp = [(int(e["t_ns"]), int(e["end_ns"])) for e in rec_events(events, rec, ("score", "annotated"))
          if e.get("end_ns") is not None and e.get("placement") in (None, placement)]
    return (min(a for a, _ in sp), max(b for _, b in sp)) if sp else None


def event_side(e: dict) -> str:
    return e.get("side") or (e.get("placement") or "").removeprefix("foot_")


def stride_reference_lengths(mine: list[dict], ref, events: list[dict], rec: dict, side: str) -> None:
    """``stride_length_ref_m`` of the foot's stride rows ``mine`` from the optical foot positions ``ref``
    ((t_ns, (M, 3))), within the reference's labelled strides when it has them."""
    from stridelab.estimators.gait.evaluation import stride_length_reference
    if not mine:
        return
    t0 = int(ref[0][0]) if len(ref[0]) else 0
    labelled = [(e["t_ns"], e["end_ns"]) for e in rec_events(events, rec, ("stride",))
                if event_side(e) == side and e.get("end_ns") is not None]
    lens = stride_length_reference((np.array([[r["start_ns"], r["end_ns"]] for r in mine]) - t0) / 1e9,
                                   (ref[0] - t0) / 1e9, ref[1],
                                   (np.array(labelled, np.int64) - t0) / 1e9 if labelled else None)
    for r, v in zip(mine, lens):
        r["stride_length_ref_m"] = num(v)


def event_rows(sid: str, det: dict, ref: dict, spans: dict, tol_s: float,
               origin_ns: int) -> tuple[list[dict], list[dict]]:
    """det/ref: (side, type) -> list over trials of int64 ns arrays; spans: side -> list over trials of the span
    the reference annotates ((lo, hi) ns, or None). Rows for accuracy_metrics/accuracy_pairs (``spans_s``)."""
    from stridelab.estimators.gait.evaluation import event_accuracy
    metrics, pairs = [], []
    units = {"sensitivity": "fraction", "precision": "fraction", "timing_mae_ms": "ms", "timing_mean_ms": "ms"}
    sec = lambda x: (np.asarray(x, np.int64) - origin_ns) / 1e9          # noqa: E731
    for typ in ("IC", "TC"):
        groups = {f"foot_{s}": [s] for s in SIDES}
        groups["both"] = list(SIDES)
        for placement, sides in groups.items():
            d = [sec(x) for s in sides for x in det.get((s, typ), [])]
            r = [sec(x) for s in sides for x in ref.get((s, typ), [])]
            if not any(len(x) for x in r):
                continue
            # a trial without an annotated span: event_accuracy's own default, [first - tol, last + tol] reference
            trial_spans = [sp for s in sides for sp in spans.get(s, [])]
            sp = [tuple(sec(np.array(span))) if span is not None else
                  ((x.min() - tol_s, x.max() + tol_s) if len(x) else (0.0, 0.0))
                  for span, x in zip(trial_spans, r)]
            acc = event_accuracy(d, r, tolerance_s=tol_s, spans_s=sp)
            for name, unit in units.items():
                v = num(getattr(acc, name))
                if v is not None:
                    metrics.append({"session_id": sid, "stage": "gait_events", "estimator": ESTIMATOR,
                                    "placement": placement, "metric": f"{typ.lower()}_{name}", "value": v,
                                    "unit": unit})
            if placement != "both":
                pairs += [{"session_id": sid, "stage": "gait_events", "estimator": ESTIMATOR, "placement": placement,
                           "quantity": typ, "estimate": float(a + origin_ns / 1e9),
                           "reference": float(b + origin_ns / 1e9), "unit": "s"} for a, b in acc.pairs_s]
    return metrics, pairs


def trajectory_rows(sid: str, placement: str, t_ns: np.ndarray, trajs: list, ref, notes: list, trial) -> list[dict]:
    """Foot trajectory vs the optical foot position (PyShoe's Vicon): 2-D Euclidean ARMSE after PyShoe's alignment
    (the scorer of ``stridelab bench trajectory --pyshoe``), per segment with a reference on at least half its
    samples, pooled weighted by length; and the 3-D error after the same alignment (metric ``armse_3d_m``).
    ``trajs``: the stored trajectories ``(a, b, TrajectoryResult)`` of the segments."""
    from stridelab.estimators.trajectory.evaluation import armse_2d_aligned, armse_3d_aligned
    rt, rp = ref
    if len(rt) < 2:
        return []
    half = 0.5 * float(np.median(np.diff(rt)))
    parts = []
    for a, b, tr in trajs:
        if tr.status != "ok":
            continue
        t = t_ns[a:b]
        j = np.clip(np.searchsorted(rt, t), 1, len(rt) - 1)
        j -= (t - rt[j - 1]) < (rt[j] - t)
        on = np.where((np.abs(rt[j] - t) <= half)[:, None], rp[j], np.nan)
        if np.all(np.isfinite(on), axis=1).mean() < 0.5:
            continue
        try:
            e, _ = armse_2d_aligned(tr.pos, on)
            e3 = armse_3d_aligned(tr.pos, on)
        except ValueError as err:
            notes.append(f"{trial} {placement}: trajectory not scored ({err})")
            continue
        if np.isfinite(e):
            parts.append((e, b - a, e3))
    if not parts:
        return []
    v = float(np.average([p[0] for p in parts], weights=[p[1] for p in parts]))
    rows = [{"session_id": sid, "stage": "foot_trajectory", "estimator": ESTIMATOR, "placement": placement,
             "metric": "armse_2d_m", "value": v, "unit": "m"}]
    if all(np.isfinite(p[2]) for p in parts):
        rows.append({**rows[0], "metric": "armse_3d_m",
                     "value": float(np.average([p[2] for p in parts], weights=[p[1] for p in parts]))})
    return rows


def stride_rows(sid: str, strides: list[dict]) -> list[dict]:
    """Stride length against the optical reference per foot and both: MAE, mean error, RMSE."""
    from stridelab.estimators.gait.evaluation import paired_errors
    rows = []
    for placement, sides in (("foot_left", ("left",)), ("foot_right", ("right",)), ("both", SIDES)):
        sel = [r for r in strides if r["side"] in sides and r["stride_length_ref_m"] is not None
               and r["stride_length_m"] is not None]
        if not sel:
            continue
        e = paired_errors([r["stride_length_m"] for r in sel], [r["stride_length_ref_m"] for r in sel])
        rows += [{"session_id": sid, "stage": "strides", "estimator": ESTIMATOR, "placement": placement,
                  "metric": f"stride_length_{k}_m", "value": num(e[k]), "unit": "m"} for k in ("mae", "mean", "rmse")
                 if num(e[k]) is not None]
    return rows
