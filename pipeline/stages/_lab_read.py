"""The lower-limb IMUs of one lab recording on one time grid, with their orientations: what the calibration and
joint-angle stages read (:func:`read_recording`), and the calibration trial of a session."""
from __future__ import annotations

import numpy as np

from stridelab.estimators.sync import clock_fit, common_grid, interp_columns, nlerp, to_clock_of
from stridelab.pipeline.stages._context import StageContext

CALIBRATION_TRIAL = "calibration"
#: when the stamps shared by every sensor are fewer than this share of the shortest sensor's, the
#: sensors run on independent clocks and are resampled onto one grid (see :func:`read_recording`)
EXACT_GRID_SHARE = 0.9


def find_calibration_recording(recordings: list[dict]) -> dict | None:
    """The session's calibration trial (the last one if it was repeated), or None."""
    cands = [r for r in recordings if (r.get("trial") or "").lower() == CALIBRATION_TRIAL]
    return cands[-1] if cands else None


def read_recording(ctx: StageContext, rec: dict, orientation_rows: list[dict], placements) -> dict:
    """acc, gyr, quat (placement -> (N, ·) on the common grid), t_ns and sampling_rate_hz of one recording.

    Placements without an IMU are left out; ``quat`` only holds placements with orientation rows.
    Sensors sharing one clock meet on the stamps they all have (no interpolation). Sensors on
    independent clocks (offsets up to seconds, jitter, slightly different rates: the shared stamps are
    fewer than :data:`EXACT_GRID_SHARE` of the shortest sensor's) are aligned through the host clock
    (:func:`stridelab.estimators.sync.clock_fit`), which maps every stamp into the clock of the first placement, and the
    others are interpolated (linearly; the orientation by nlerp) onto that sensor's stamps where all overlap.
    ``resampled`` tells which case applied; the grid is empty when the sensors do not overlap.
    """
    series, quat_t = {}, {}
    ori = {r["placement"]: r for r in orientation_rows if r["content_hash"] == rec["content_hash"]}
    rate = None
    for p in placements:
        s = ctx.read_imu_files(rec, p)
        if s is None:
            continue
        series[p] = s
        rate = rate or float(rec["sensors"][p]["imu"]["sampling_rate_hz"])
        if p in ori:
            t = ctx.read_table(ori[p]["series_path"])
            quat_t[p] = (t.column("t_ns").to_numpy(),
                         np.column_stack([t.column(c).to_numpy() for c in ("qw", "qx", "qy", "qz")]))
    grid = common_grid({p: s.t_ns for p, s in series.items()})
    shortest = min((len(s.t_ns) for s in series.values()), default=0)
    if len(series) > 1 and len(grid) < EXACT_GRID_SHARE * shortest:
        return _resampled(ctx, rec, series, quat_t, rate)

    def on_grid(t, x):
        return x[np.searchsorted(t, grid)]

    out = {"t_ns": grid, "sampling_rate_hz": rate, "acc": {}, "gyr": {}, "quat": {}, "resampled": False}
    for p, s in series.items():
        out["acc"][p], out["gyr"][p] = on_grid(s.t_ns, s.acc), on_grid(s.t_ns, s.gyr)
        if p in quat_t and np.isin(grid, quat_t[p][0]).all():
            out["quat"][p] = on_grid(*quat_t[p])
    return out


def _resampled(ctx: StageContext, rec: dict, series: dict, quat_t: dict, rate: float) -> dict:
    """The independent-clock case of :func:`read_recording`."""
    fits = {}
    for p in series:
        tab = ctx.read_table(rec["sensors"][p]["imu"]["series_path"], ["t_ns", "log_ns"])
        fits[p] = clock_fit(tab.column("t_ns").to_numpy(), tab.column("log_ns").to_numpy())
    ref = next(iter(series))
    mapped = {p: to_clock_of(s.t_ns, fits[p], fits[ref]) for p, s in series.items()}
    lo = max(m[0] for m in mapped.values())
    hi = min(m[-1] for m in mapped.values())
    t_ref = series[ref].t_ns
    keep = (t_ref >= lo) & (t_ref <= hi)
    grid = t_ref[keep]
    out = {"t_ns": grid, "sampling_rate_hz": rate, "acc": {}, "gyr": {}, "quat": {}, "resampled": True}
    g = grid.astype(np.float64)
    for p, s in series.items():
        if p == ref:
            out["acc"][p], out["gyr"][p] = s.acc[keep], s.gyr[keep]
        else:
            out["acc"][p], out["gyr"][p] = interp_columns(g, mapped[p], s.acc), interp_columns(g, mapped[p], s.gyr)
        if p in quat_t and len(quat_t[p][0]) >= 2 and len(grid):
            out["quat"][p] = nlerp(to_clock_of(quat_t[p][0], fits[p], fits[ref]), quat_t[p][1], g)
    return out


def session_calibration(rows: list[dict]):
    """:class:`SessionCalibration` rebuilt from the calibration stage's rows (None when there are none)."""
    import json

    from stridelab.estimators.calibration import CalibrationParams, CalibrationWindows, ImuCalibration, SessionCalibration
    from stridelab.estimators.quaternion import quat_to_matrix
    if not rows:
        return None
    imus = {}
    for r in rows:
        q = [r[f"q{k}"] for k in "wxyz"]
        R = quat_to_matrix(np.asarray(q, float)) if all(v is not None for v in q) else np.full((3, 3), np.nan)
        imus[r["placement"]] = ImuCalibration(r["placement"], R, r["method"] or "none", r["status"],
                                              tuple(json.loads(r["reasons"] or "[]")), n_cycles=int(r["n_reps"] or 0))
    p = json.loads(rows[0]["params"] or "{}")
    fields = CalibrationParams.__dataclass_fields__
    cp = CalibrationParams(**{k: v for k, v in p.items() if k in fields})
    return SessionCalibration(imus=imus, windows=CalibrationWindows(), status=rows[0]["session_status"],
                              reasons=tuple(json.loads(rows[0]["session_reasons"] or "[]")), params=cp)


def ic_times_by_side(upstream: dict) -> dict[str, np.ndarray] | None:
    """Initial contacts (int64 ns) per side from an upstream ``gait_events`` table, or None if absent (rows with
    ``side`` or a ``foot_<side>`` placement and either ``type`` = IC and ``t_ns``, or ``ic_ns``)."""
    rows = upstream.get("gait_events")
    if rows is None:
        return None
    out: dict[str, list[int]] = {"left": [], "right": []}
    for r in rows:
        side = r.get("side") or (r.get("placement") or r.get("foot") or "").removeprefix("foot_")
        if side not in out:
            continue
        if r.get("ic_ns") is not None:
            out[side].append(int(r["ic_ns"]))
        elif str(r.get("type", "")).lower() in ("ic", "initial_contact") and r.get("t_ns") is not None:
            out[side].append(int(r["t_ns"]))
    return {s: np.unique(np.asarray(v, np.int64)) for s, v in out.items()}
