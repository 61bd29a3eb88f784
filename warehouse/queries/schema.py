"""What a snapshot holds: the stage outputs the queries read (:data:`DATASETS`), which of them a snapshot has,
the hint shown when one is missing, and the SQL helpers every query module uses."""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import pandas as pd


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


def _has_column(con, table: str, column: str) -> bool:
    return bool(con.execute("SELECT count(*) FROM information_schema.columns WHERE table_schema = 'main' "
                            "AND table_name = ? AND column_name = ?", [table, column]).fetchall()[0][0])
