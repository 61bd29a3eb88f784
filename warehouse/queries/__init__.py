"""Every SQL query of the dashboard and the reports, on the warehouse's newest snapshot (read-only).

One module per subject (``schema``, ``overview``, ``participant``, ``gait``, ``accuracy``, ``activity``,
``clinical``, ``runs``, ``live``, ``trunk_gait``); this package re-exports every name, so callers write
``from stridelab.warehouse import queries as Q`` and ``Q.sessions(con, ...)``. Two layers:

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

from typing import Callable

from stridelab.warehouse.queries.schema import (DATASETS, Dataset, RUN_HINT, available, missing_hint, table_columns)
from stridelab.warehouse.queries.overview import (counts, last_run, participants, qc_flags, quarantined, stage_coverage,
                                                  studies)
from stridelab.warehouse.queries.participant import (orientation_coverage, participant_issues, participant_studies,
                                                  recordings, sessions)
from stridelab.warehouse.queries.gait import (GAIT_PARAMS, GAIT_SYMMETRY, calibration_qc, foot_trajectories,
                                              gait_summary, joint_cycles, strides)
from stridelab.warehouse.queries.accuracy import (accuracy_filters, accuracy_metrics, accuracy_pairs,
                                                  accuracy_provenance, posture_confusion, stride_length_pairs,
                                                  with_provenance)
from stridelab.warehouse.queries.activity import (ACTIVITY_CLASSES, ACTIVITY_COLORS, POSTURES, WALKING_CLASSES,
                                                  activity_bouts, activity_daily, activity_participants, walking_bouts,
                                                  walking_summary)
from stridelab.warehouse.queries.clinical import (CLINICAL_SHOWN, clinical_series, clinical_visits, programme_change)
from stridelab.warehouse.queries.runs import (ingest_topics, pipeline_runs, skipped_topics, stage_durations, stage_runs)
from stridelab.warehouse.queries.live import (live_agreement, live_agreement_strides)
from stridelab.warehouse.queries.trunk_gait import (BOUT_CLASSES, capacity_and_performance, daily_gait_outcomes,
                                                    trunk_gait_participants, trunk_walking_bouts)


# ---- registry of the queries (the dashboard's cached access: dashboard/snapshot.py) ---------

#: not queries of a snapshot (helpers and types)
_NOT_QUERIES = {"table_columns", "missing_hint", "Dataset"}


def _registry() -> dict[str, Callable]:
    out = {}
    for name, obj in sorted(globals().items()):
        if callable(obj) and str(getattr(obj, "__module__", "")).startswith(__name__ + ".") \
                and not name.startswith("_") and name not in _NOT_QUERIES:
            out[name] = obj
    return out


QUERIES: dict[str, Callable] = _registry()
