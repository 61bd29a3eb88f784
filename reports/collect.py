"""What a participant's report shows, read from one warehouse snapshot as DataFrames (None = stage not run yet).

Only the pseudonym identifies the participant; file names (which may carry site identifiers) are not read into
the report.
"""
from __future__ import annotations

from pathlib import Path

from stridelab.warehouse import queries as Q

def collect(con, root: Path, participant_id: str, study: str | None) -> dict:
    """Everything the report shows, as DataFrames (None = stage not run yet)."""
    studies = Q.participant_studies(con, participant_id)
    if not studies:
        raise LookupError(f"participant {participant_id!r} is not in the warehouse (check the pseudonym)")
    if study is None:
        if len(studies) > 1:
            raise ValueError(f"participant {participant_id!r} exists in studies {', '.join(studies)}: pass --study")
        study = studies[0]
    elif study not in studies:
        raise LookupError(f"participant {participant_id!r} is not in study {study!r} (found in: {', '.join(studies)})")
    ses = Q.sessions(con, participant_id, study)
    strides = Q.strides(con, participant_id, study)
    acc = Q.accuracy_metrics(con)
    if acc is not None and "session_id" in acc:
        acc = acc[acc["session_id"].isin(ses["session_id"])]
    pairs = Q.stride_length_pairs(con, study)
    if pairs is not None:
        pairs = pairs[pairs["participant_id"] == participant_id]
    if pairs is None or pairs.empty:
        ap = Q.accuracy_pairs(con)
        if ap is not None and "session_id" in ap:
            ap = ap[ap["session_id"].isin(ses["session_id"]) & ap["quantity"].str.contains("stride_length")]
            pairs = ap if not ap.empty else pairs
    return {
        "participant_id": participant_id, "study": study, "sessions": ses,
        "recordings": Q.recordings(con, participant_id, study),
        "issues": Q.participant_issues(con, participant_id, study),
        "strides": strides, "gait": Q.gait_summary(con, participant_id, study),
        "joints": Q.joint_cycles(con, participant_id, study), "calibration": Q.calibration_qc(con, participant_id, study),
        "daily": Q.activity_daily(con, participant_id, study), "accuracy": acc, "stride_pairs": pairs,
        "orientation": Q.orientation_coverage(con, participant_id, study),
        "clinical": Q.clinical_visits(con, study, participant_id),
        "walking": Q.walking_bouts(con, participant_id, study),
        "home_days": Q.daily_gait_outcomes(con, participant_id, study),
        "home_bouts": Q.trunk_walking_bouts(con, participant_id, study),
        "capacity": Q.capacity_and_performance(con, participant_id, study),
    }
