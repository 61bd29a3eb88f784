"""Daily activity (chest sensor): activity participants, bouts, daily totals and free-living walking bouts."""
from __future__ import annotations

import numpy as np
import pandas as pd

from stridelab.warehouse.queries.schema import _df, _has_table


#: activity classes in display order, with fixed colours (dashboard and reports)
ACTIVITY_CLASSES = ("lying", "sitting", "standing", "level_walking", "stairs_up", "stairs_down", "non_wear")


ACTIVITY_COLORS = {"lying": "#4c78a8", "sitting": "#72b7b2", "standing": "#54a24b", "level_walking": "#f58518",
                   "stairs_up": "#e45756", "stairs_down": "#b279a2", "non_wear": "#bab0ac"}


POSTURES = ("lying", "sitting", "standing")


def activity_participants(con) -> pd.DataFrame:
    if not _has_table(con, "activity_bouts"):
        return pd.DataFrame(columns=["study", "participant_id"])
    return _df(con, f"""
        SELECT DISTINCT s.study, s.participant_id FROM activity_bouts b JOIN sessions s
        ON s.session_id = b.session_id ORDER BY 1, 2""")


def _bouts_local() -> str:
    """SELECT of a participant's bouts with their local start and end (the session's time zone); parameters:
    participant_id, study, study. Shared by :func:`activity_bouts` and :func:`activity_daily`."""
    return """
            SELECT s.session_id, CAST(b.class AS VARCHAR) AS class, b.start_ns, b.end_ns,
                   CAST(b.steps AS DOUBLE) AS steps,
                   timezone(coalesce(s.timezone, 'UTC'), make_timestamptz(b.start_ns // 1000)) AS start_local,
                   timezone(coalesce(s.timezone, 'UTC'), make_timestamptz(b.end_ns // 1000)) AS end_local
            FROM activity_bouts b JOIN sessions s ON s.session_id = b.session_id
            WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)"""


def activity_bouts(con, participant_id: str, study: str | None = None, day: str | None = None) -> pd.DataFrame | None:
    """Bouts of a participant (local day and times in the session's time zone), optionally of one day."""
    if not _has_table(con, "activity_bouts"):
        return None
    return _df(con, f"""
        WITH x AS ({_bouts_local()})
        SELECT *, CAST(start_local AS DATE) AS day, (end_ns - start_ns) / 1e9 AS seconds FROM x
        WHERE (? IS NULL OR CAST(start_local AS DATE) = CAST(? AS DATE))
        ORDER BY start_ns""", [participant_id, study, study, day, day])


def activity_daily(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    """Per local day and class: hours, steps, bouts; plus posture transitions per day (class '_transitions').

    Bouts that cross local midnight are split at midnight (steps pro rata), so a day never exceeds 24 h.
    """
    if not _has_table(con, "activity_bouts"):
        return None
    return _df(con, f"""
        WITH x AS (
            SELECT session_id, class, start_ns, steps, start_local AS t0, end_local AS t1
            FROM ({_bouts_local()}) WHERE end_ns > start_ns),
        d AS (
            SELECT x.*, CAST(dd AS DATE) AS day,
                   epoch(least(t1, CAST(dd AS DATE) + INTERVAL 1 DAY) - greatest(t0, CAST(dd AS TIMESTAMP))) AS seconds,
                   epoch(t1 - t0) AS total_s
            FROM x, unnest(generate_series(date_trunc('day', t0), t1, INTERVAL 1 DAY)) AS g(dd)),
        p AS (SELECT CAST(t0 AS DATE) AS day, class,
                     lag(class) OVER (PARTITION BY session_id ORDER BY start_ns) AS prev FROM x
              WHERE class IN ('lying', 'sitting', 'standing'))
        SELECT day, class, sum(seconds) / 3600.0 AS hours, sum(steps * seconds / total_s) AS steps, count(*) AS bouts
        FROM d WHERE seconds > 0 GROUP BY ALL
        UNION ALL
        SELECT day, '_transitions' AS class, NULL AS hours, NULL AS steps, count(*) AS bouts
        FROM p WHERE prev IS NOT NULL AND prev <> class GROUP BY day
        ORDER BY day, class""", [participant_id, study, study])


WALKING_CLASSES = ("level_walking", "stairs_up", "stairs_down")


def walking_bouts(con, participant_id: str, study: str | None = None) -> pd.DataFrame | None:
    """Walking bouts of the chest days (the activity stage's bouts of a walking class; consecutive walking classes
    joined into one bout): session, local start, duration, steps, cadence within the bout (steps/min)."""
    b = activity_bouts(con, participant_id, study)
    if b is None:
        return None
    b = b.sort_values(["session_id", "start_ns"]).reset_index(drop=True)
    walk = b["class"].isin(WALKING_CLASSES).to_numpy()
    if not walk.any():
        return pd.DataFrame(columns=["session_id", "day", "start_local", "hour", "seconds", "steps", "cadence_spm"])
    # a new bout starts at a walking row whose previous row (same session) is not walking or is not contiguous
    prev_walk = np.r_[False, walk[:-1]] & (b["session_id"].to_numpy() == np.r_[None, b["session_id"].to_numpy()[:-1]])
    contiguous = np.r_[False, b["start_ns"].to_numpy()[1:] <= b["end_ns"].to_numpy()[:-1] + 1_000_000_000]
    new = walk & ~(prev_walk & contiguous)
    bout_id = np.cumsum(new)
    w = b[walk].assign(bout=bout_id[walk])
    out = w.groupby("bout").agg(session_id=("session_id", "first"), start_local=("start_local", "first"),
                                start_ns=("start_ns", "first"), end_ns=("end_ns", "last"),
                                steps=("steps", lambda x: x.sum(min_count=1)))
    out["seconds"] = (out["end_ns"] - out["start_ns"]) / 1e9
    out["day"] = pd.to_datetime(out["start_local"]).dt.date.astype(str)
    out["hour"] = pd.to_datetime(out["start_local"]).dt.hour
    out["cadence_spm"] = np.where(out["seconds"] > 0, 60.0 * out["steps"] / out["seconds"], np.nan)
    return out.reset_index(drop=True)[["session_id", "day", "start_local", "hour", "seconds", "steps", "cadence_spm"]]


def walking_summary(bouts: pd.DataFrame) -> pd.DataFrame:
    """Per chest day: steps, walking minutes, bouts, median and longest bout, median cadence in bouts ≥ 60 s, share
    of the walking time in bouts ≥ 60 s."""
    if bouts is None or bouts.empty:
        return pd.DataFrame(columns=["session_id", "day", "steps", "walking_min", "bouts", "median_bout_s",
                                     "longest_bout_s", "cadence_long_bouts_spm", "share_in_long_bouts_pct"])
    rows = []
    for (sid, day), g in bouts.groupby(["session_id", "day"], sort=True):
        long = g[g["seconds"] >= 60]
        rows.append({"session_id": sid, "day": day, "steps": g["steps"].sum(min_count=1),
                     "walking_min": g["seconds"].sum() / 60, "bouts": len(g), "median_bout_s": g["seconds"].median(),
                     "longest_bout_s": g["seconds"].max(),
                     "cadence_long_bouts_spm": long["cadence_spm"].median() if len(long) else np.nan,
                     "share_in_long_bouts_pct": 100 * long["seconds"].sum() / g["seconds"].sum()
                     if g["seconds"].sum() else np.nan})
    return pd.DataFrame(rows)
