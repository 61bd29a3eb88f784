"""A participant: studies, sessions, recordings, ingest issues and orientation coverage."""
from __future__ import annotations

import pandas as pd

from stridelab.warehouse.queries.overview import qc_flags
from stridelab.warehouse.queries.schema import _df, _has_column, _has_table


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
