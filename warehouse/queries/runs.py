"""Pipeline runs: runs, stage runs and their durations, skipped topics and ingest topics."""
from __future__ import annotations

import pandas as pd

from stridelab.warehouse.queries.schema import _df, _has_column, _has_table, _lst


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
