"""Lab gait: strides, the gait stage's per-session summary, joint-angle cycles, calibration QC and foot
trajectories."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from stridelab.warehouse.store import SeriesDamaged, read_table
from stridelab.warehouse.queries.schema import _df, _has_table, _select


def strides(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    """Every stride of the participant's sessions (logical column names), or None if no gait stage yet."""
    if not _has_table(con, "strides"):
        return None
    return _df(con, f"""
        SELECT s.session_id, s.kind, s.protocol, s.start_ns AS session_start_ns, {_select('t', 'strides', ('session_id',))}
        FROM strides t JOIN sessions s ON s.session_id = t.session_id
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY s.start_ns""", [participant_id, study, study])


GAIT_PARAMS = {"speed_m_s": "gait speed (m/s)", "cadence_steps_min": "cadence (steps/min)",
               "stride_length_m": "stride length (m)", "stride_time_s": "stride time (s)",
               "stance_pct": "stance (% of stride)", "clearance_m": "foot clearance (m)"}


#: symmetry indices of the gait stage (200·|L−R|/(L+R) %, on its 'both' row)
GAIT_SYMMETRY = {"si_stride_time_pct": "SI stride time (%)", "si_stride_length_pct": "SI stride length (%)",
                 "si_stance_pct": "SI stance (%)", "si_swing_time_pct": "SI swing time (%)",
                 "si_clearance_pct": "SI clearance (%)"}


def gait_summary(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    """Per session, the gait stage's ``gait_summary`` row for both feet (``side = 'both'``): cadence, speed, stride
    length and time, stance, clearance, symmetry indices and stride count as the stage computed them, with the
    session's start, protocol and date. None when the table is absent."""
    if not _has_table(con, "gait_summary"):
        return None
    df = _df(con, f"""
        SELECT s.session_id, s.start_ns AS session_start_ns, s.protocol, {_select('g', 'gait_summary', ('session_id', 'side'))}
        FROM gait_summary g JOIN sessions s ON s.session_id = g.session_id
        WHERE g.side = 'both' AND s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY s.start_ns""", [participant_id, study, study])
    df = df.rename(columns={"n_strides": "strides"})
    df["date"] = pd.to_datetime(df["session_start_ns"], unit="ns", utc=True)
    return df


def joint_cycles(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    if not _has_table(con, "joint_angle_curves"):
        return None
    return _df(con, f"""
        SELECT s.session_id, s.start_ns AS session_start_ns, {_select('t', 'joint_cycles', ('session_id',))}
        FROM joint_angle_curves t JOIN sessions s ON s.session_id = t.session_id
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY s.start_ns, t.joint, t.side""", [participant_id, study, study])


def calibration_qc(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    if not _has_table(con, "calibration"):
        return None
    return _df(con, f"""
        SELECT t.* FROM calibration t JOIN sessions s ON s.session_id = t.session_id
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY s.start_ns""", [participant_id, study, study])


def foot_trajectories(con, root: str | Path, participant_id: str, study: str | None = None,
                      max_points: int = 5000) -> pd.DataFrame | None:
    """Foot positions (x, y, z in m) of the participant's newest session with trajectories, or None."""
    if not _has_table(con, "foot_trajectories"):
        return None
    rows = con.execute(f"""
        SELECT t.session_id, t.placement, t.series_path
        FROM foot_trajectories t JOIN sessions s ON s.session_id = t.session_id
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY s.start_ns DESC""", [participant_id, study, study]).fetchall()
    if not rows:
        return pd.DataFrame()
    newest = rows[0][0]
    frames = []
    root = Path(root).resolve()
    for sid, placement, rel in rows:
        if sid != newest:
            continue
        path = (root / rel).resolve()
        if root not in path.parents or not path.is_file():
            continue
        # the series layout of the migration (foot_trajectories.series_path): t_ns, px, py, pz (m), ...
        try:         # through pyarrow: every page's checksum verified, a damaged file never served
            t = read_table(root, rel, columns=["px", "py", "pz"])
        except SeriesDamaged:
            continue
        df = pd.DataFrame({"x": t.column("px").to_numpy(), "y": t.column("py").to_numpy(),
                           "z": t.column("pz").to_numpy()})
        step = max(1, len(df) // max_points)
        df = df.iloc[::step].reset_index(drop=True)
        df["session_id"], df["placement"] = sid, placement
        frames.append(df)
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
