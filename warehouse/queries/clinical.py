"""Clinical measures per visit and the change over a programme."""
from __future__ import annotations

import numpy as np
import pandas as pd

from stridelab.warehouse.queries.schema import _df, _has_table


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
