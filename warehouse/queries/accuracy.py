"""Accuracy against references: metrics, paired values, their provenance, stride-length pairs and the posture
confusion table."""
from __future__ import annotations

import pandas as pd

from stridelab.warehouse.queries.schema import _df, _has_table, _lst


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
