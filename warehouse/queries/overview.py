"""The overview page: counts, studies, participants, the last run, quarantined files, QC flags and stage coverage."""
from __future__ import annotations

import pandas as pd

from stridelab.warehouse.queries.schema import _df, _has_table


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
