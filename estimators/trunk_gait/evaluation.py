"""The one scorer for trunk gait: initial contacts, walking bouts and per-bout parameters (used by
``stridelab bench trunk-gait``, the trunk-gait accuracy stage and the dashboard alike).

Initial contacts are matched one-to-one: a detected and a reference contact match when each is the other's
nearest and they are at most ``tolerance_s`` apart (0.25 s, the tolerance of the Mobilise-D validation, Micó-Amigo
et al. 2023, doi:10.1186/s12984-023-01198-5). With ``windows_s`` (the reference's walking: Mobilise-D INDIP
walking bouts, a Voisard trial) only the detections inside a window ± ``tolerance_s`` are scored, as Mobilise-D
validated the contact detectors within the reference walking (Micó-Amigo et al. 2023); detections elsewhere count
neither as matched nor as extra. Walking bouts are matched one-to-one by overlap: pairs in decreasing
order of intersection-over-union, each bout used once, IoU ≥ ``min_iou``. Per matched bout: absolute and relative
errors of cadence, stride length and walking speed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ICMatch", "BoutMatch", "match_initial_contacts", "ic_metrics", "match_bouts", "bout_errors",
           "summarise_bout_errors", "IC_TOLERANCE_S", "BOUT_MIN_IOU"]

IC_TOLERANCE_S = 0.25
BOUT_MIN_IOU = 0.5


@dataclass(frozen=True)
class ICMatch:
    """det_idx / ref_idx (M,) matched pairs (indices into the inputs), error_s (M,) detected - reference;
    fp_idx unmatched detections, fn_idx unmatched references."""
    det_idx: np.ndarray
    ref_idx: np.ndarray
    error_s: np.ndarray
    fp_idx: np.ndarray
    fn_idx: np.ndarray


def _nearest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Index into sorted ``b`` of the nearest element to each of ``a``."""
    j = np.clip(np.searchsorted(b, a), 1, len(b) - 1) if len(b) > 1 else np.zeros(len(a), np.int64)
    if len(b) > 1:
        j = np.where(np.abs(a - b[j - 1]) <= np.abs(a - b[j]), j - 1, j)
    return j


def match_initial_contacts(detected_s, reference_s, *, tolerance_s: float = IC_TOLERANCE_S,
                           windows_s=None) -> ICMatch:
    """Mutual-nearest one-to-one matching within ``tolerance_s`` (see module docstring). ``windows_s``: (K, 2)
    [start, end] s where contacts are scored (each ± ``tolerance_s``); detections outside all of them are left out
    (in no index array); None = everywhere. Indices refer to the full inputs."""
    if tolerance_s < 0:
        raise ValueError(f"tolerance_s must be >= 0, got {tolerance_s}")
    d = np.asarray(detected_s, float).ravel()
    r = np.asarray(reference_s, float).ravel()
    if windows_s is not None:
        w = np.asarray(windows_s, float).reshape(-1, 2)
        keep = ((d[:, None] >= w[None, :, 0] - tolerance_s) & (d[:, None] <= w[None, :, 1] + tolerance_s)).any(axis=1)
        kept = np.flatnonzero(keep)
        m = match_initial_contacts(d[kept], r, tolerance_s=tolerance_s)
        return ICMatch(det_idx=kept[m.det_idx], ref_idx=m.ref_idx, error_s=m.error_s, fp_idx=kept[m.fp_idx],
                       fn_idx=m.fn_idx)
    od, orf = np.argsort(d, kind="stable"), np.argsort(r, kind="stable")
    ds, rs = d[od], r[orf]
    if len(ds) == 0 or len(rs) == 0:
        e = np.empty(0, np.int64)
        return ICMatch(e, e, np.empty(0), od.astype(np.int64), orf.astype(np.int64))
    dn = _nearest(ds, rs)
    rn = _nearest(rs, ds)
    i = np.arange(len(ds))
    ok = (rn[dn] == i) & (np.abs(ds - rs[dn]) <= tolerance_s)
    di, ri = i[ok], dn[ok]
    fp = np.setdiff1d(np.arange(len(ds)), di)
    fn = np.setdiff1d(np.arange(len(rs)), ri)
    return ICMatch(det_idx=od[di], ref_idx=orf[ri], error_s=ds[di] - rs[ri], fp_idx=od[fp], fn_idx=orf[fn])


def ic_metrics(m: ICMatch) -> dict:
    """sensitivity (TP / references), precision (TP / detections), F1, timing MAE and bias (s), counts."""
    tp, fp, fn = len(m.det_idx), len(m.fp_idx), len(m.fn_idx)
    nan = float("nan")
    return {"tp": tp, "fp": fp, "fn": fn,
            "sensitivity": tp / (tp + fn) if tp + fn else nan,
            "precision": tp / (tp + fp) if tp + fp else nan,
            "f1": 2 * tp / (2 * tp + fp + fn) if tp + fp + fn else nan,
            "timing_mae_s": float(np.mean(np.abs(m.error_s))) if tp else nan,
            "timing_bias_s": float(np.mean(m.error_s)) if tp else nan}


@dataclass(frozen=True)
class BoutMatch:
    """det_idx / ref_idx (M,) matched bouts, iou (M,); fp_idx / fn_idx unmatched detected / reference bouts."""
    det_idx: np.ndarray
    ref_idx: np.ndarray
    iou: np.ndarray
    fp_idx: np.ndarray
    fn_idx: np.ndarray


def match_bouts(det_start_s, det_end_s, ref_start_s, ref_end_s, *, min_iou: float = BOUT_MIN_IOU) -> BoutMatch:
    """One-to-one matching of [start, end] intervals by intersection-over-union ≥ ``min_iou`` (greedy by IoU)."""
    if not 0 < min_iou <= 1:
        raise ValueError(f"min_iou must be in (0, 1], got {min_iou}")
    ds, de = np.asarray(det_start_s, float).ravel(), np.asarray(det_end_s, float).ravel()
    rs, re = np.asarray(ref_start_s, float).ravel(), np.asarray(ref_end_s, float).ravel()
    if len(ds) != len(de) or len(rs) != len(re):
        raise ValueError("start and end arrays must have the same length")
    inter = np.clip(np.minimum(de[:, None], re[None, :]) - np.maximum(ds[:, None], rs[None, :]), 0, None)
    union = (de - ds)[:, None] + (re - rs)[None, :] - inter
    iou = np.where(union > 0, inter / np.where(union > 0, union, 1), 0.0)
    pairs = np.argwhere(iou >= min_iou)
    order = np.argsort(-iou[pairs[:, 0], pairs[:, 1]], kind="stable")
    used_d, used_r, md, mr = set(), set(), [], []
    for a, b in pairs[order]:
        if a not in used_d and b not in used_r:
            used_d.add(a)
            used_r.add(b)
            md.append(a)
            mr.append(b)
    md, mr = np.asarray(md, np.int64), np.asarray(mr, np.int64)
    return BoutMatch(det_idx=md, ref_idx=mr, iou=iou[md, mr] if len(md) else np.empty(0),
                     fp_idx=np.setdiff1d(np.arange(len(ds)), md), fn_idx=np.setdiff1d(np.arange(len(rs)), mr))


def bout_errors(m: BoutMatch, det: dict, ref: dict) -> dict:
    """Per matched bout, for each key present in both ``det`` and ``ref`` (arrays over bouts, e.g.
    ``cadence_spm``, ``stride_length_m``, ``walking_speed_m_s``): ``{key: {"error": det - ref (M,),
    "abs_error": (M,), "pct_error": 100 |det - ref| / ref (M,)}}``; NaN where either is NaN."""
    out = {}
    for k in det:
        if k not in ref:
            continue
        d = np.asarray(det[k], float)[m.det_idx]
        r = np.asarray(ref[k], float)[m.ref_idx]
        err = d - r
        out[k] = {"error": err, "abs_error": np.abs(err),
                  "pct_error": np.where(np.abs(r) > 0, 100.0 * np.abs(err) / np.where(r == 0, 1, np.abs(r)),
                                        np.nan)}
    return out


def summarise_bout_errors(errs: list[dict]) -> dict:
    """Pool per-bout errors of several recordings: ``cadence_mape_pct``, ``stride_length_mae_m``,
    ``walking_speed_mae_m_s`` (None where no bout had that reference) and the number of bouts per key."""
    def pooled(key, field):
        xs = [e[key][field] for e in errs if key in e]
        x = np.concatenate(xs) if xs else np.empty(0)
        x = x[np.isfinite(x)]
        return (float(np.mean(x)) if len(x) else None), int(len(x))
    cad, n_cad = pooled("cadence_spm", "pct_error")
    sl, n_sl = pooled("stride_length_m", "abs_error")
    ws, n_ws = pooled("walking_speed_m_s", "abs_error")
    return {"cadence_mape_pct": cad, "stride_length_mae_m": sl, "walking_speed_mae_m_s": ws,
            "n_bouts_cadence": n_cad, "n_bouts_stride_length": n_sl, "n_bouts_speed": n_ws}
