"""Live sessions: the agreement of the live results with the batch results."""
from __future__ import annotations

import pandas as pd

from stridelab.warehouse.queries.schema import _df, _has_table


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
