"""Every SQL query of the dashboard and the reports, on the warehouse's newest snapshot (read-only).

Two layers:

* plain functions ``name(con, ...) -> pandas.DataFrame`` (no Streamlit): the reports and the
  benchmark call them with their own connection;
* :data:`QUERIES`, the registry the dashboard's cached access (``dashboard/snapshot.py``: one cached read-only
  connection per published snapshot, ``st.cache_data`` on every query keyed by the snapshot name) runs by name;
  this module never imports Streamlit.

Filter values reach SQL **only as parameters** (``?``). Identifiers (table and column names) come
from ``information_schema`` of the snapshot itself, never from user input, and are quoted.

The stage outputs are the tables the migrations create (``warehouse/migrations``), listed in :data:`DATASETS`
(table and the columns the queries read); the queries name the real tables and columns directly, and return
them under those names. A snapshot made before a migration may lack a table: its queries then return None and a
page shows a hint of what to run. The gait parameters shown are the gait stage's own
``gait_summary`` rows (cadence, symmetry), never recomputed here.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from stridelab.warehouse.store import read_table, SeriesDamaged


RUN_HINT = "run `stridelab run --inbox INBOX --warehouse WAREHOUSE` (or `stridelab demo --no-serve`)"


@dataclass(frozen=True)
class Dataset:
    """A stage output the dashboard and the reports show: its table, the columns the queries read (the names
    the migrations give them), and what computes it (for the hint)."""
    table: str
    columns: tuple[str, ...]
    produced_by: str


#: stage outputs, as the migrations (warehouse/migrations/*.sql) create them
DATASETS: dict[str, Dataset] = {
    "strides": Dataset("strides", (
        "session_id", "trial", "side", "ic_ns", "tc_ns", "stride_time_s", "stance_pct", "swing_pct", "stride_length_m",
        "speed_m_s", "clearance_m", "turning_deg", "stride_length_ref_m", "status"),
        "the gait stage (gait events and strides)"),
    "gait_summary": Dataset("gait_summary", (
        "session_id", "side", "cadence_steps_min", "speed_m_s", "stride_length_m", "stride_time_s", "stance_pct",
        "swing_pct", "double_support_pct", "clearance_m", "si_stride_length_pct", "si_stride_time_pct",
        "si_stance_pct", "si_swing_time_pct", "si_clearance_pct", "n_strides", "status", "note"),
        "the gait stage (per-session gait summary)"),
    "calibration": Dataset("calibration", ("session_id", "placement", "status", "reasons", "method", "n_reps"),
                           "the calibration stage"),
    "joint_cycles": Dataset("joint_angle_curves", ("session_id", "joint", "side", "plane", "pct", "mean_deg",
                                                   "sd_deg"), "the joint-angle stage"),
    "activity_bouts": Dataset("activity_bouts", ("session_id", "start_ns", "end_ns", "class", "steps"),
                              "the daily-activity stage (chest sensor)"),
    "accuracy": Dataset("accuracy_metrics", ("session_id", "stage", "estimator", "placement", "metric", "value",
                                             "unit"), "the accuracy stage (where a reference exists)"),
    "accuracy_pairs": Dataset("accuracy_pairs", ("session_id", "stage", "estimator", "placement", "quantity",
                                                 "estimate", "reference", "unit"),
                              "the accuracy stage (paired estimate/reference values)"),
    "foot_trajectory": Dataset("foot_trajectories", ("session_id", "placement", "series_path"),
                               "the foot-trajectory stage"),
}


def _select(alias: str, name: str, skip: tuple[str, ...] = ()) -> str:
    """``alias.col, ...`` over a dataset's columns (their real names), without ``skip``."""
    return ", ".join(f"{alias}.{c}" for c in DATASETS[name].columns if c not in skip)


#: activity classes in display order, with fixed colours (dashboard and reports)
ACTIVITY_CLASSES = ("lying", "sitting", "standing", "level_walking", "stairs_up", "stairs_down", "non_wear")
ACTIVITY_COLORS = {"lying": "#4c78a8", "sitting": "#72b7b2", "standing": "#54a24b", "level_walking": "#f58518",
                   "stairs_up": "#e45756", "stairs_down": "#b279a2", "non_wear": "#bab0ac"}
POSTURES = ("lying", "sitting", "standing")


# ---- schema ---------------------------------------------------------------------------------

def table_columns(con) -> dict[str, list[str]]:
    rows = con.execute("SELECT table_name, column_name FROM information_schema.columns "
                       "WHERE table_schema = 'main' ORDER BY table_name, ordinal_position").fetchall()
    out: dict[str, list[str]] = {}
    for t, c in rows:
        out.setdefault(t, []).append(c)
    return out


def available(con) -> dict[str, bool]:
    """Which stage outputs this snapshot holds (their table with the columns the queries read)."""
    schema = table_columns(con)
    return {name: ds.table in schema and set(ds.columns) <= set(schema[ds.table]) for name, ds in DATASETS.items()}


def missing_hint(name: str) -> str:
    ds = DATASETS[name]
    return (f"No {name.replace('_', ' ')} in this warehouse yet: they are computed by {ds.produced_by}; "
            f"{RUN_HINT}. Expected table: {ds.table}.")


def _df(con, sql: str, params: list | None = None) -> pd.DataFrame:
    """The query's rows as a DataFrame. DuckDB 2.0's own conversion of a TIMESTAMPTZ column calls
    ``DataFrame.drop(inplace=True)``, which pandas 3.1 deprecates (Pandas4Warning, PDEP-8): not a call of ours, so
    that one warning is silenced here, where the conversion happens, and no other."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="The inplace keyword in DataFrame.drop is deprecated",
                                category=getattr(pd.errors, "Pandas4Warning", DeprecationWarning))
        return con.execute(sql, params or []).df()


def _has_table(con, table: str) -> bool:
    return bool(con.execute("SELECT count(*) FROM information_schema.tables WHERE table_schema = 'main' "
                            "AND table_name = ?", [table]).fetchall()[0][0])


def _lst(values) -> list[str] | None:
    """Multiselect value -> SQL list parameter (None or empty means 'all')."""
    if values is None:
        return None
    vals = [str(v) for v in values]
    return vals or None


# ---- overview -------------------------------------------------------------------------------

def counts(con) -> dict:
    r = con.execute("""
        SELECT (SELECT count(DISTINCT study) FROM sessions),
               (SELECT count(*) FROM participants),
               (SELECT count(*) FROM sessions),
               (SELECT count(*) FROM recordings WHERE status = 'ingested'),
               (SELECT count(*) FROM recordings WHERE status = 'quarantined'),
               (SELECT count(*) FROM recording_issues)""").fetchall()[0]
    return dict(zip(("studies", "participants", "sessions", "recordings", "quarantined", "issues"), r))


def studies(con) -> pd.DataFrame:
    return _df(con, """
        SELECT p.study, count(DISTINCT p.participant_id) AS participants, count(DISTINCT s.session_id) AS sessions,
               count(DISTINCT s.session_id) FILTER (WHERE s.kind = 'lab') AS lab_sessions,
               count(DISTINCT s.session_id) FILTER (WHERE s.kind = 'free_living') AS free_living_sessions,
               make_timestamptz(min(s.start_ns) // 1000) AS first_session,
               make_timestamptz(max(s.end_ns) // 1000) AS last_session
        FROM participants p LEFT JOIN sessions s USING (study, participant_id)
        GROUP BY p.study ORDER BY p.study""")


def participants(con, study: str | None = None) -> pd.DataFrame:
    return _df(con, """
        SELECT p.study, p.participant_id, count(DISTINCT s.session_id) AS sessions,
               count(DISTINCT r.content_hash) AS recordings,
               make_timestamptz(max(s.end_ns) // 1000) AS last_data
        FROM participants p
        LEFT JOIN sessions s USING (study, participant_id)
        LEFT JOIN recordings r ON r.session_id = s.session_id AND r.status = 'ingested'
        WHERE (? IS NULL OR p.study = ?)
        GROUP BY p.study, p.participant_id ORDER BY p.study, p.participant_id""", [study, study])


def last_run(con) -> dict | None:
    rows = con.execute("""
        SELECT run_id, command, status, started_at, finished_at,
               date_diff('millisecond', started_at, finished_at) / 1000.0 AS duration_s,
               n_ingested, n_quarantined, n_stage_runs, n_failed, version, host
        FROM pipeline_runs ORDER BY started_at DESC LIMIT 1""")
    names = [d[0] for d in rows.description]
    r = rows.fetchall()
    return dict(zip(names, r[0])) if r else None


def quarantined(con) -> pd.DataFrame:
    return _df(con, """
        SELECT file_name, reason, ingested_at AS seen_at, content_hash
        FROM recordings WHERE status = 'quarantined' ORDER BY ingested_at DESC NULLS LAST, file_name""")


def qc_flags(con) -> pd.DataFrame:
    """Data-quality flags: recording issues, failed stages (latest attempt), failed calibration QC."""
    parts = ["""
        SELECT 'recording' AS source, s.study, s.participant_id, r.session_id, i.severity,
               coalesce(i.topic, '') AS what, i.message
        FROM recording_issues i JOIN recordings r USING (content_hash)
        LEFT JOIN sessions s ON s.session_id = r.session_id""", """
        SELECT 'stage' AS source, s.study, s.participant_id, x.session_id, 'error' AS severity,
               x.stage AS what, x.error AS message
        FROM (SELECT *, row_number() OVER (PARTITION BY session_id, stage ORDER BY started_at DESC) AS k
              FROM stage_runs) x
        LEFT JOIN sessions s USING (session_id)
        WHERE x.k = 1 AND x.status = 'failed'"""]
    if _has_table(con, "calibration"):
        parts.append(f"""
        SELECT 'calibration' AS source, s.study, s.participant_id, c.session_id AS session_id,
               'warning' AS severity, CAST(c.placement AS VARCHAR) AS what,
               concat_ws(': ', CAST(c.status AS VARCHAR), CAST(c.reasons AS VARCHAR)) AS message
        FROM calibration c LEFT JOIN sessions s ON s.session_id = c.session_id
        WHERE CAST(c.status AS VARCHAR) <> 'pass'""")   # status: pass | warn | fail (migration 003)
    return _df(con, " UNION ALL ".join(parts) + " ORDER BY source, study, participant_id, session_id")


def stage_coverage(con) -> pd.DataFrame:
    """Per stage: sessions done (latest ok), skipped (the session lacks what the stage needs), failed, and the
    newest version."""
    return _df(con, """
        SELECT stage, count(*) FILTER (WHERE status = 'ok') AS sessions_ok,
               count(*) FILTER (WHERE status = 'skipped') AS sessions_skipped,
               count(*) FILTER (WHERE status = 'failed') AS sessions_failed,
               max(stage_version) AS version
        FROM (SELECT *, row_number() OVER (PARTITION BY session_id, stage ORDER BY started_at DESC) AS k
              FROM stage_runs) WHERE k = 1
        GROUP BY stage ORDER BY stage""")


# ---- participant ----------------------------------------------------------------------------

def participant_studies(con, participant_id: str) -> list[str]:
    return [r[0] for r in con.execute("SELECT study FROM participants WHERE participant_id = ? ORDER BY study",
                                      [participant_id]).fetchall()]


def sessions(con, participant_id: str | None = None, study: str | None = None) -> pd.DataFrame:
    return _df(con, """
        SELECT s.study, s.participant_id, s.session_id, s.kind, s.protocol, s.timezone,
               make_timestamptz(s.start_ns // 1000) AS start, make_timestamptz(s.end_ns // 1000) AS "end",
               (s.end_ns - s.start_ns) / 3.6e12 AS hours,
               count(r.content_hash) AS recordings, string_agg(DISTINCT r.trial, ', ' ORDER BY r.trial) AS trials
        FROM sessions s LEFT JOIN recordings r ON r.session_id = s.session_id AND r.status = 'ingested'
        WHERE (? IS NULL OR s.participant_id = ?) AND (? IS NULL OR s.study = ?)
        GROUP BY s.study, s.participant_id, s.session_id, s.kind, s.protocol, s.timezone, s.start_ns, s.end_ns
        ORDER BY s.start_ns, s.session_id""", [participant_id, participant_id, study, study])


def _has_column(con, table: str, column: str) -> bool:
    return bool(con.execute("SELECT count(*) FROM information_schema.columns WHERE table_schema = 'main' "
                            "AND table_name = ? AND column_name = ?", [table, column]).fetchall()[0][0])


def recordings(con, participant_id: str, study: str | None = None) -> pd.DataFrame:
    # crc: 'unverified' for a file written without CRCs (migration 013), '' otherwise (and before 013)
    crc = ("CASE WHEN r.crc_verified = false THEN 'unverified' ELSE '' END"
           if _has_column(con, "recordings", "crc_verified") else "''")
    return _df(con, f"""
        SELECT r.session_id, r.trial, r.file_name, r.status, {crc} AS crc, r.n_samples,
               (r.end_ns - r.start_ns) / 1e9 AS seconds,
               (SELECT string_agg(DISTINCT placement, ', ' ORDER BY placement) FROM sensors x
                 WHERE x.content_hash = r.content_hash AND x.kind = 'imu') AS imus,
               (SELECT count(*) FROM recording_issues i WHERE i.content_hash = r.content_hash) AS issues
        FROM recordings r JOIN sessions s ON s.session_id = r.session_id
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY r.start_ns, r.file_name""", [participant_id, study, study])


def participant_issues(con, participant_id: str, study: str | None = None) -> pd.DataFrame:
    q = qc_flags(con)
    if q.empty:
        return q
    m = q["participant_id"] == participant_id
    if study is not None:
        m &= q["study"] == study
    return q[m].reset_index(drop=True)


def orientation_coverage(con, participant_id: str, study: str | None = None) -> pd.DataFrame:
    if not _has_table(con, "orientation"):
        return pd.DataFrame(columns=["session_id", "placement", "estimator", "n_samples", "mag_used"])
    return _df(con, """
        SELECT o.session_id, o.placement, o.estimator, o.estimator_version, o.n_samples, o.sampling_rate_hz, o.mag_used
        FROM orientation o JOIN sessions s USING (session_id)
        WHERE s.participant_id = ? AND (? IS NULL OR s.study = ?)
        ORDER BY o.session_id, o.placement""", [participant_id, study, study])


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


# ---- accuracy -------------------------------------------------------------------------------

def accuracy_filters(con) -> dict[str, list[str]]:
    """Values offered by the accuracy filters (studies, estimators, placements, trial types)."""
    out = {"study": [r[0] for r in con.execute("SELECT DISTINCT study FROM sessions ORDER BY 1").fetchall()],
           "estimator": [], "placement": [], "trial": []}
    if not _has_table(con, "accuracy_metrics"):
        return out
    for k in ("estimator", "placement"):
        out[k] = [x[0] for x in con.execute(f"SELECT DISTINCT CAST({k} AS VARCHAR) FROM accuracy_metrics "
                                            f"WHERE {k} IS NOT NULL ORDER BY 1").fetchall()]
    # the trial type of an accuracy row is its session's protocol
    out["trial"] = [x[0] for x in con.execute(
        "SELECT DISTINCT CAST(s.protocol AS VARCHAR) FROM accuracy_metrics t LEFT JOIN sessions s "
        "ON s.session_id = t.session_id WHERE s.protocol IS NOT NULL ORDER BY 1").fetchall()]
    return out


def _acc_where(alias: str = "t") -> tuple[str, str]:
    """Join + WHERE clause for the four accuracy filters; parameters: study, estimator, placement, trial lists."""
    join = f"LEFT JOIN sessions s ON s.session_id = {alias}.session_id"
    est = f"CAST({alias}.estimator AS VARCHAR)"
    pl = f"CAST({alias}.placement AS VARCHAR)"
    trial = "s.protocol"
    where = (f"(?::VARCHAR[] IS NULL OR list_contains(?::VARCHAR[], s.study)) "
             f"AND (?::VARCHAR[] IS NULL OR list_contains(?::VARCHAR[], {est})) "
             f"AND (?::VARCHAR[] IS NULL OR list_contains(?::VARCHAR[], {pl})) "
             f"AND (?::VARCHAR[] IS NULL OR list_contains(?::VARCHAR[], {trial}))")
    return join, where


def _acc_params(study, estimator, placement, trial) -> list:
    out = []
    for v in (study, estimator, placement, trial):
        v = _lst(v)
        out += [v, v]
    return out


def accuracy_metrics(con, study=None, estimator=None, placement=None, trial=None) -> pd.DataFrame | None:
    """Accuracy rows (stage, estimator, placement, metric, value, unit, session, study, trial) after filters."""
    if not _has_table(con, "accuracy_metrics"):
        return None
    join, where = _acc_where()
    m = _df(con, f"""
        SELECT t.stage, t.metric, CAST(t.value AS DOUBLE) AS value, s.study, s.protocol AS trial,
               t.estimator, t.placement, t.unit, t.session_id
        FROM accuracy_metrics t {join} WHERE {where}
        ORDER BY 1, 2""", _acc_params(study, estimator, placement, trial))
    return with_provenance(m, accuracy_provenance(con))


#: what a stage's accuracy is scored against when the recording declares nothing more specific
_REFERENCE_BY_STAGE = {"orientation": "optical segment orientation (/reference/pose/<placement>)",
                       "calibration": "optical segment orientation (/reference/pose/<placement>)",
                       "joint_angles": "optical segment poses of both segments (/reference/pose)",
                       "gait_events": "annotated gait events (/reference/events IC/TC)",
                       "strides": "optical foot position (/reference/pose/<foot>)",
                       "foot_trajectory": "optical foot position (/reference/pose/<foot>)",
                       "activity": "activity labels (/reference/events)"}


def accuracy_provenance(con) -> pd.DataFrame:
    """Per session: ``data`` (study · protocol · recordings) and the references the recordings declare
    (session field ``reference``, sources of the reference events by kind)."""
    if not _has_table(con, "reference_events"):
        return pd.DataFrame(columns=["session_id", "dataset", "data", "ref_declared", "ev_source", "act_source"])
    return _df(con, """
        WITH rec AS (
            SELECT r.session_id, count(*) AS n,
                   string_agg(DISTINCT json_extract_string(r.metadata, '$.reference'), '; ') AS ref_declared,
                   min(r.file_name) AS first_file
            FROM recordings r WHERE r.status = 'ingested' GROUP BY 1),
        ev AS (
            SELECT session_id,
                   string_agg(DISTINCT json_extract_string(payload, '$.source'), '; ')
                       FILTER (WHERE upper(type) IN ('IC', 'TC')) AS ev_source,
                   string_agg(DISTINCT json_extract_string(payload, '$.source'), '; ')
                       FILTER (WHERE type = 'activity') AS act_source
            FROM reference_events GROUP BY 1)
        SELECT s.session_id, s.study || ' · ' || coalesce(s.protocol, s.kind) AS dataset,
               s.study || ' · ' || coalesce(s.protocol, s.kind) || ' · ' ||
                   CASE WHEN rec.n = 1 THEN rec.first_file ELSE rec.n || ' recordings' END AS data,
               rec.ref_declared, ev.ev_source, ev.act_source
        FROM sessions s LEFT JOIN rec USING (session_id) LEFT JOIN ev USING (session_id)""")


def with_provenance(m: pd.DataFrame, prov: pd.DataFrame) -> pd.DataFrame:
    """Accuracy rows + ``dataset`` (study · protocol), ``data`` (+ the file or number of recordings) and
    ``reference`` columns: what each row was computed on and scored against."""
    if m is None or m.empty or "session_id" not in m:
        return m
    out = m.merge(prov, on="session_id", how="left")

    def ref(r) -> str:
        stage = str(r["stage"])
        if stage == "gait_events" and isinstance(r.get("ev_source"), str):
            return r["ev_source"]
        if stage == "activity" and isinstance(r.get("act_source"), str):
            return r["act_source"]
        if isinstance(r.get("ref_declared"), str):
            return r["ref_declared"]
        return _REFERENCE_BY_STAGE.get(stage, "reference topics of the recording")

    out["reference"] = out.apply(ref, axis=1) if len(out) else pd.Series(dtype=str)
    out["data"] = out["data"].fillna(out["session_id"])
    out["dataset"] = out["dataset"].fillna(out["study"])
    return out.drop(columns=["ref_declared", "ev_source", "act_source"])


def accuracy_pairs(con, study=None, estimator=None, placement=None, trial=None) -> pd.DataFrame | None:
    """Paired estimate/reference values (for Bland–Altman and event timing errors) after filters."""
    if not _has_table(con, "accuracy_pairs"):
        return None
    join, where = _acc_where()
    extra = "t.stage, t.estimator, t.placement, t.unit, t.session_id"
    return _df(con, f"""
        SELECT t.quantity AS quantity, CAST(t.estimate AS DOUBLE) AS estimate,
               CAST(t.reference AS DOUBLE) AS reference, s.study{', ' + extra if extra else ''}
        FROM accuracy_pairs t {join} WHERE {where}""", _acc_params(study, estimator, placement, trial))


def stride_length_pairs(con, study=None) -> pd.DataFrame | None:
    """IMU vs reference stride length from the strides table when it carries a reference column."""
    if not _has_table(con, "strides"):
        return None
    return _df(con, f"""
        SELECT CAST(t.stride_length_m AS DOUBLE) AS estimate,
               CAST(t.stride_length_ref_m AS DOUBLE) AS reference, s.study, s.participant_id
        FROM strides t JOIN sessions s ON s.session_id = t.session_id
        WHERE t.stride_length_ref_m IS NOT NULL AND (? IS NULL OR s.study = ?)""", [study, study])


def posture_confusion(con, study: str | None = None, participant_id: str | None = None) -> pd.DataFrame | None:
    """Seconds of overlap between reference activity labels and classified activity bouts.

    Reference: ``reference_events`` of type ``activity`` (t_ns..end_ns, label); classified: the
    activity stage's bouts of the same session. None when the activity stage has not run.
    """
    if not _has_table(con, "activity_bouts"):
        return None
    return _df(con, f"""
        SELECT e.label AS reference, CAST(b.class AS VARCHAR) AS predicted,
               sum(least(e.end_ns, b.end_ns) - greatest(e.t_ns, b.start_ns)) / 1e9 AS seconds
        FROM reference_events e
        JOIN sessions s ON s.session_id = e.session_id
        JOIN activity_bouts b ON b.session_id = e.session_id
             AND b.start_ns < e.end_ns AND b.end_ns > e.t_ns
        WHERE e.type = 'activity' AND e.end_ns IS NOT NULL
          AND (? IS NULL OR s.study = ?) AND (? IS NULL OR s.participant_id = ?)
        GROUP BY 1, 2 ORDER BY 1, 2""", [study, study, participant_id, participant_id])


# ---- activity -------------------------------------------------------------------------------

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


# ---- clinical measures and programme change ------------------------------------------------------

#: clinical measures shown in the dashboard and report: (measure, quantity) -> human name. quantity "value" is the
#: session value, "symmetry_ratio" the larger/smaller ratio (docs/clinical_measures.md)
CLINICAL_SHOWN = {("gait_speed_m_s", "value"): "Gait speed (m/s)",
                  ("cadence_steps_min", "value"): "Cadence (steps/min)",
                  ("step_time_s", "symmetry_ratio"): "Step time symmetry ratio",
                  ("swing_time_s", "symmetry_ratio"): "Swing time symmetry ratio",
                  ("stance_time_s", "symmetry_ratio"): "Stance time symmetry ratio",
                  ("single_support_s", "symmetry_ratio"): "Single support symmetry ratio",
                  ("step_length_m", "symmetry_ratio"): "Step length symmetry ratio",
                  ("double_support_pct", "value"): "Double support (% of stride)",
                  ("stride_length_m", "value"): "Stride length (m)"}


def clinical_visits(con, study: str | None = None, participant_id: str | None = None) -> pd.DataFrame | None:
    """Clinical measures of every lab session with its visit number (1 = first lab session of the participant)."""
    if not _has_table(con, "clinical_measures"):
        return None
    return _df(con, """
        WITH v AS (SELECT session_id, study, participant_id, start_ns,
                          row_number() OVER (PARTITION BY study, participant_id ORDER BY start_ns, session_id) AS visit
                   FROM sessions WHERE kind = 'lab')
        SELECT v.study, v.participant_id, v.session_id, v.visit, make_timestamptz(v.start_ns // 1000) AS date,
               c.measure, c.unit, c.value, c.sem, c.mdc95, c.left_value, c.right_value, c.n_left, c.n_right,
               c.cv_left_pct, c.cv_right_pct, c.paretic_side, c.paretic_value, c.non_paretic_value, c.paretic_ratio,
               c.symmetry_ratio, c.sem_symmetry_ratio, c.mdc95_symmetry_ratio, c.flag, c.note,
               coalesce(rb.repeat_baseline, false) AS repeat_baseline
        FROM clinical_measures c JOIN v ON v.session_id = c.session_id
        LEFT JOIN (SELECT session_id, bool_or(json_extract_string(metadata, '$.repeat_baseline') = '1')
                          AS repeat_baseline
                   FROM recordings WHERE status = 'ingested' GROUP BY session_id) rb ON rb.session_id = c.session_id
        WHERE (? IS NULL OR v.study = ?) AND (? IS NULL OR v.participant_id = ?)
        ORDER BY v.study, v.participant_id, v.visit, c.measure""", [study, study, participant_id, participant_id])


def clinical_series(visits: pd.DataFrame, measure: str, quantity: str = "value") -> pd.DataFrame:
    """One measure per participant and visit: value, its SEM, flag (from :func:`clinical_visits`)."""
    sem_col = "sem" if quantity == "value" else f"sem_{quantity}"
    v = visits[visits["measure"] == measure]
    out = v[["study", "participant_id", "session_id", "visit", "date", "flag", "n_left", "n_right"]].copy()
    out["value"] = v[quantity].astype(float)
    out["sem"] = v[sem_col].astype(float) if sem_col in v else np.nan
    return out.reset_index(drop=True)


def programme_change(visits: pd.DataFrame, measure: str, quantity: str = "value",
                     against: str = "first") -> pd.DataFrame:
    """Per participant: the latest visit against the first (``against="first"``) or the previous one
    (``"previous"``), change, its MDC95 from between-session error (:func:`stridelab.estimators.gait.clinical.change_mdc95`:
    the study's repeated baseline sessions, session field ``repeat_baseline = 1``, when it has them; else the
    published test-retest value at the baseline; else NaN, and "beyond noise" stays unknown), where that MDC comes
    from (``mdc_source``), and whether the change exceeds it. Never the within-session SEM."""
    from stridelab.estimators.gait.clinical import change_mdc95
    s = clinical_series(visits, measure, quantity)
    rep = visits[visits["measure"] == measure] if "repeat_baseline" in visits else visits.iloc[:0]
    rep = rep[rep["repeat_baseline"].fillna(False).astype(bool)] if len(rep) else rep
    rows = []
    for (study, pid), g in s.groupby(["study", "participant_id"], sort=True):
        g = g.sort_values("visit")
        a, b = g.iloc[0 if against == "first" or len(g) < 2 else -2], g.iloc[-1]
        ch = float(b["value"] - a["value"]) if len(g) > 1 else np.nan
        r = rep[rep["study"] == study]
        repeated = [x[quantity].astype(float).to_numpy() for _, x in r.groupby("participant_id")] if len(r) else None
        m = change_mdc95(measure, quantity, baseline=float(a["value"]), repeated_baselines=repeated)
        mdc = m.mdc95 if len(g) > 1 else np.nan
        rows.append({"study": study, "participant_id": pid, "visits": len(g), "baseline": a["value"],
                     "latest": b["value"] if len(g) > 1 else np.nan, "change": ch, "mdc95": mdc,
                     "mdc_source": m.source if len(g) > 1 else "",
                     "beyond_mdc": bool(np.isfinite(ch) and np.isfinite(mdc) and abs(ch) > mdc),
                     "mdc_known": bool(np.isfinite(mdc)),
                     "flag": ", ".join(sorted({f for f in g["flag"].fillna("") if f}))})
    return pd.DataFrame(rows, columns=["study", "participant_id", "visits", "baseline", "latest", "change", "mdc95",
                                       "mdc_source", "beyond_mdc", "mdc_known", "flag"])


# ---- free-living walking bouts ---------------------------------------------------------------------

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


# ---- runs -----------------------------------------------------------------------------------

def pipeline_runs(con, limit: int = 200) -> pd.DataFrame:
    return _df(con, """
        SELECT run_id, command, status, started_at, finished_at,
               date_diff('millisecond', started_at, finished_at) / 1000.0 AS duration_s,
               n_ingested, n_quarantined, n_stage_runs, n_failed, jobs, version, host
        FROM pipeline_runs ORDER BY started_at DESC LIMIT ?""", [int(limit)])


def stage_runs(con, run_id: str | None = None, status: str | None = None, stage=None, limit: int = 2000) -> pd.DataFrame:
    return _df(con, """
        SELECT r.run_id, r.stage, r.stage_version, r.session_id, s.participant_id, r.status, r.started_at,
               r.duration_s, r.cpu_s, r.error, r.note
        FROM stage_runs r LEFT JOIN sessions s USING (session_id)
        WHERE (? IS NULL OR r.run_id = ?) AND (? IS NULL OR r.status = ?)
          AND (?::VARCHAR[] IS NULL OR list_contains(?::VARCHAR[], r.stage))
        ORDER BY r.started_at DESC, r.stage, r.session_id LIMIT ?""",
               [run_id, run_id, status, status, _lst(stage), _lst(stage), int(limit)])


def stage_durations(con) -> pd.DataFrame:
    return _df(con, """
        SELECT stage, count(*) AS runs, count(*) FILTER (WHERE status = 'failed') AS failed,
               avg(duration_s) AS mean_s, quantile_cont(duration_s, 0.5) AS median_s, max(duration_s) AS max_s,
               sum(duration_s) AS total_s, avg(cpu_s) AS mean_cpu_s, sum(cpu_s) AS total_cpu_s
        FROM stage_runs GROUP BY stage ORDER BY stage""")


def skipped_topics(con, limit: int = 500) -> pd.DataFrame:
    """Topics of ingested or refused files that were not ingested, each with its reason: from the ingest ledger
    (``ingest_topics``, migration 015: every run, the file's outcome when the whole file was refused), and for
    recordings ingested before it, from ``recordings.skipped_topics`` (migration 013)."""
    cols = ["run_id", "file_name", "status", "topic", "reason", "ingested_at"]
    parts, params = [], []
    ledger = _has_table(con, "ingest_topics")
    if ledger:
        parts.append("""
        SELECT t.run_id, t.file_name, t.outcome AS status, t.topic, t.reason, p.started_at AS ingested_at
        FROM ingest_topics t LEFT JOIN pipeline_runs p USING (run_id) WHERE t.outcome <> 'ingested'""")
    if _has_column(con, "recordings", "skipped_topics"):
        parts.append(f"""
        SELECT NULL AS run_id, r.file_name, r.status, s.value ->> 'topic' AS topic, s.value ->> 'reason' AS reason,
               r.ingested_at
        FROM recordings r, json_each(r.skipped_topics) s
        WHERE r.skipped_topics IS NOT NULL
          {"AND r.content_hash NOT IN (SELECT content_hash FROM ingest_topics)" if ledger else ""}""")
    if not parts:
        return pd.DataFrame(columns=cols)
    return _df(con, f"""
        SELECT * FROM ({" UNION ALL ".join(parts)})
        ORDER BY ingested_at DESC NULLS LAST, file_name, topic LIMIT ?""", params + [limit])


def ingest_topics(con, run_id: str | None = None, limit: int = 2000) -> pd.DataFrame:
    """The ingest ledger (migration 015): every topic of every file a run read, with its outcome (ingested,
    skipped, quarantined, reexport, duplicate), placement, samples and reason."""
    cols = ["run_id", "file_name", "topic", "outcome", "placement", "n_samples", "reason"]
    if not _has_table(con, "ingest_topics"):
        return pd.DataFrame(columns=cols)
    return _df(con, f"""
        SELECT {", ".join("t." + c for c in cols)}
        FROM ingest_topics t LEFT JOIN pipeline_runs p USING (run_id)
        WHERE (? IS NULL OR t.run_id = ?)
        ORDER BY p.started_at DESC NULLS LAST, t.file_name, t.outcome <> 'ingested', t.topic LIMIT ?""",
               [run_id, run_id, int(limit)])


def live_agreement(con) -> pd.DataFrame:
    """Per live recording (stridelab live, migration 014): its agreement with the nightly, one row per
    comparison, quantity, key and metric (``online_filter``: the same online estimators rerun offline;
    ``offline_smoothed``: the nightly's own outputs)."""
    cols = ["session_id", "participant_id", "comparison", "quantity", "key", "metric", "value", "unit"]
    if not _has_table(con, "live_agreement"):
        return pd.DataFrame(columns=cols)
    return _df(con, """
        SELECT a.session_id, s.participant_id, a.comparison, a.quantity, a.key, a.metric, a.value, a.unit
        FROM live_agreement a LEFT JOIN sessions s USING (session_id)
        ORDER BY a.session_id, a.quantity, a.key, a.comparison, a.metric""")


def live_agreement_strides(con, session_id: str | None = None) -> pd.DataFrame:
    """Live minus offline per stride and joint plane (migration 014)."""
    if not _has_table(con, "live_agreement_strides"):
        return pd.DataFrame(columns=["session_id", "side", "joint", "plane", "start_ns", "end_ns", "n_frames",
                                     "max_abs_diff_online_deg", "max_abs_diff_offline_deg", "rmse_offline_deg"])
    return _df(con, """
        SELECT session_id, side, joint, plane, start_ns, end_ns, n_frames, max_abs_diff_online_deg,
               max_abs_diff_offline_deg, rmse_offline_deg
        FROM live_agreement_strides WHERE ? IS NULL OR session_id = ?
        ORDER BY session_id, side, joint, plane, start_ns""", [session_id, session_id])


# ---- registry of the queries (the dashboard's cached access: dashboard/snapshot.py) ---------

_QUERIES: dict[str, Callable] = {}


def _register() -> None:
    for name, obj in list(globals().items()):
        if callable(obj) and getattr(obj, "__module__", None) == __name__ and not name.startswith("_") \
                and name not in {"resolve", "table_columns", "missing_hint", "open_snapshot",
                                 "Dataset"}:
            _QUERIES[name] = obj


_register()

QUERIES = _QUERIES


# ---- walking at home: trunk-gait bouts and daily outcomes (migration 012) ---------------------------------------

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


_register()      # the walking-at-home queries above join the registry
