"""Walking at home (migration 012): trunk-gait participants, walking bouts, daily gait outcomes and capacity
against performance."""
from __future__ import annotations

import numpy as np
import pandas as pd

from stridelab.warehouse.queries.schema import _df, _has_table


#: bout-duration classes of the daily outcomes, [lo, hi) s -> daily_gait_outcomes column
BOUT_CLASSES = {"10-30 s": "n_bouts_10_30s", "30-60 s": "n_bouts_30_60s", "60-120 s": "n_bouts_60_120s",
                "> 120 s": "n_bouts_over_120s"}


def trunk_gait_participants(con, study: str | None = None) -> pd.DataFrame | None:
    """Participants with trunk-gait walking bouts or daily outcomes: study, participant_id, home days, lab
    sessions with bouts."""
    if not (_has_table(con, "walking_bouts") and _has_table(con, "daily_gait_outcomes")):
        return None
    return _df(con, """
        SELECT s.study, s.participant_id,
               count(DISTINCT d.session_id || d.date) AS home_days,
               count(DISTINCT CASE WHEN s.kind = 'lab' THEN b.session_id END) AS lab_sessions_with_bouts
        FROM sessions s
        LEFT JOIN daily_gait_outcomes d ON d.session_id = s.session_id
        LEFT JOIN walking_bouts b ON b.session_id = s.session_id
        WHERE (? IS NULL OR s.study = ?) AND (d.session_id IS NOT NULL OR b.session_id IS NOT NULL)
        GROUP BY ALL ORDER BY 1, 2""", [study, study])


def trunk_walking_bouts(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    """The trunk-gait stage's walking bouts of a participant with the session kind and local start/day."""
    if not _has_table(con, "walking_bouts"):
        return None
    return _df(con, """
        SELECT b.*, s.kind, s.study, s.participant_id,
               timezone(coalesce(s.timezone, 'UTC'), make_timestamptz(b.start_ns // 1000)) AS start_local,
               CAST(timezone(coalesce(s.timezone, 'UTC'), make_timestamptz(b.start_ns // 1000)) AS DATE) AS day
        FROM walking_bouts b JOIN sessions s ON s.session_id = b.session_id
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY b.start_ns""", [participant_id, study, study])


def daily_gait_outcomes(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    """Per home day (free-living session × local date) the daily gait outcomes of a participant."""
    if not _has_table(con, "daily_gait_outcomes"):
        return None
    return _df(con, """
        SELECT d.*, s.study, s.participant_id, s.start_ns AS session_start_ns
        FROM daily_gait_outcomes d JOIN sessions s ON s.session_id = d.session_id
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY d.date, d.session_id""", [participant_id, study, study])


def capacity_and_performance(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    """Lab capacity beside home performance per visit period of a participant: each lab visit (clinical gait
    speed from the gait stage's strides, ``clinical_measures``) with the home days from that visit up to the next
    one (daily median and 95th centile of walking speed over bouts > 10 s, walking time); columns visit, lab_date,
    lab_speed_m_s, home_days, home_speed_median_m_s (median of the days' medians), home_speed_p95_m_s (median of
    the days' p95), walking_min_per_day, days_with_long_bouts."""
    if not _has_table(con, "daily_gait_outcomes"):
        return None
    lab = _df(con, """
        SELECT s.session_id, s.start_ns,
               row_number() OVER (ORDER BY s.start_ns, s.session_id) AS visit
        FROM sessions s WHERE s.kind = 'lab' AND s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY s.start_ns""", [participant_id, study, study])
    speed = {}
    if _has_table(con, "clinical_measures") and len(lab):
        speed = dict(con.execute("SELECT session_id, value FROM clinical_measures WHERE measure = 'gait_speed_m_s' "
                                 "AND session_id IN (SELECT unnest(?))", [lab["session_id"].tolist()]).fetchall())
    days = daily_gait_outcomes(con, participant_id, study)
    rows = []
    bounds = lab["start_ns"].tolist()
    for i, r in lab.iterrows():
        lo, hi = bounds[i], bounds[i + 1] if i + 1 < len(bounds) else None
        d = days[(days["session_start_ns"] >= lo) & ((days["session_start_ns"] < hi) if hi is not None else True)]
        rows.append({"visit": int(r["visit"]), "lab_session": r["session_id"],
                     "lab_date": pd.Timestamp(int(r["start_ns"]), unit="ns", tz="UTC").date().isoformat(),
                     "lab_speed_m_s": speed.get(r["session_id"], np.nan), "home_days": int(len(d)),
                     "home_speed_median_m_s": float(d["speed_median_m_s"].median()) if len(d) else np.nan,
                     "home_speed_p95_m_s": float(d["speed_p95_m_s"].median()) if len(d) else np.nan,
                     "walking_min_per_day": float(d["walking_time_s"].mean() / 60.0) if len(d) else np.nan,
                     "days_with_long_bouts": int((d["n_bouts_over_10s"] > 0).sum()) if len(d) else 0})
    return pd.DataFrame(rows, columns=["visit", "lab_session", "lab_date", "lab_speed_m_s", "home_days",
                                       "home_speed_median_m_s", "home_speed_p95_m_s", "walking_min_per_day",
                                       "days_with_long_bouts"])
