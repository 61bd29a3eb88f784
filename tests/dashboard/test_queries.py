"""Queries: filter values reach SQL only as parameters; optional stage tables are resolved by schema."""
from __future__ import annotations

import duckdb
import numpy as np
import pytest

from stridelab.warehouse import queries as Q
from stridelab.warehouse.read import connect_snapshot

HOSTILE = ["x' OR '1'='1", "'; DROP TABLE sessions; --", "P001\" OR 1=1 --", "%", "*", "P001'/*", "\x00"]


@pytest.fixture()
def con(full_wh):
    c = connect_snapshot(full_wh)
    yield c
    c.close()


@pytest.mark.parametrize("value", HOSTILE)
def test_hostile_filter_values_match_nothing_and_change_nothing(con, value):
    before = con.execute("SELECT count(*) FROM sessions").fetchall()[0][0]
    assert Q.sessions(con, value).empty
    assert Q.recordings(con, value).empty
    assert Q.participants(con, value).empty
    assert Q.strides(con, value).empty
    assert Q.activity_daily(con, value).empty
    assert Q.accuracy_metrics(con, study=[value]).empty
    assert Q.accuracy_metrics(con, estimator=[value], placement=[value], trial=[value]).empty
    assert Q.stage_runs(con, run_id=value).empty
    assert Q.stage_runs(con, stage=[value]).empty
    assert con.execute("SELECT count(*) FROM sessions").fetchall()[0][0] == before


def test_filters_restrict_rows(con):
    allm = Q.accuracy_metrics(con)
    vqf = Q.accuracy_metrics(con, estimator=["vqf"])
    assert 0 < len(vqf) < len(allm) and set(vqf["estimator"]) == {"vqf"}
    assert len(Q.accuracy_metrics(con, estimator=[])) == len(allm)      # nothing selected = all
    assert set(Q.sessions(con, "P002")["session_id"]) == {"S03"}


def test_datasets_absent_then_resolved(ingested_wh, full_wh):
    c = connect_snapshot(ingested_wh)
    try:
        # the fixture ran the registered stages on short trials: whatever exists resolves, activity
        # (no free-living recording here) has nothing
        a = Q.activity_daily(c, "P001")
        assert a is None or len(a) == 0
        assert "stridelab run" in Q.missing_hint("strides")
    finally:
        c.close()
    c = connect_snapshot(full_wh)
    try:
        assert all(Q.available(c).values())
    finally:
        c.close()


def test_datasets_are_the_tables_the_migrations_create(empty_wh):
    """Every dataset the pages read is one table of the migrated schema, with its real column names."""
    c = connect_snapshot(empty_wh)
    try:
        schema = Q.table_columns(c)
        for name, ds in Q.DATASETS.items():
            assert ds.table in schema, name
            assert set(ds.columns) <= set(schema[ds.table]), (name, set(ds.columns) - set(schema[ds.table]))
        assert all(Q.available(c).values())
    finally:
        c.close()


def test_tables_the_migrations_never_create_are_not_read():
    c = duckdb.connect()
    c.execute("CREATE TABLE gait_strides (session_id VARCHAR, foot VARCHAR, duration_s DOUBLE, gait_speed_m_s DOUBLE)")
    c.execute("CREATE TABLE calibration_qc (session_id VARCHAR, placement VARCHAR, status VARCHAR)")
    c.execute("CREATE TABLE sessions (session_id VARCHAR, participant_id VARCHAR, study VARCHAR, start_ns BIGINT, "
              "kind VARCHAR, protocol VARCHAR)")
    av = Q.available(c)
    assert not av["strides"] and not av["calibration"]
    assert Q.strides(c, "P001") is None and Q.calibration_qc(c, "P001") is None


def test_joint_cycles_come_with_the_tables_column_names(con):
    """No alias layer: the joint-angle curves come back under joint_angle_curves' own column names."""
    j = Q.joint_cycles(con, "P001")
    assert j is not None and {"session_id", "joint", "side", "plane", "pct", "mean_deg", "sd_deg"} <= set(j.columns)
    assert "cycle_pct" not in j


def test_gait_summary_is_the_stage_table(con):
    """The dashboard shows the gait stage's gait_summary rows as they are (cadence not recomputed from strides)."""
    g = Q.gait_summary(con, "P001")
    raw = con.execute("SELECT g.cadence_steps_min, g.n_strides FROM gait_summary g JOIN sessions s USING (session_id) "
                      "WHERE s.participant_id = 'P001' AND g.side = 'both' ORDER BY s.start_ns").fetchall()
    assert len(g) == len(raw) > 0
    np.testing.assert_allclose(g["cadence_steps_min"], [r[0] for r in raw])
    assert list(g["strides"]) == [r[1] for r in raw]


def test_activity_days_are_local_days(con):
    daily = Q.activity_daily(con, "P001")
    per_day = daily[daily["class"] != "_transitions"].groupby("day")["hours"].sum()
    assert (per_day <= 24.0 + 1e-6).all()                 # bouts crossing midnight are split there
    np.testing.assert_allclose(per_day.iloc[1:-1], 24.0, atol=1e-6)     # full days in the session's time zone
    assert per_day.sum() == pytest.approx(9 * 24.0)      # nothing lost: the session lasts 9 days


def test_the_package_re_exports_every_public_name_of_its_subject_modules_and_no_module_shadows_one():
    """warehouse/queries/ is one module per subject; callers use ``Q.name``. A subject module named like a query
    (``sessions``) would shadow it for documentation tools: no package attribute that a module defines is a module."""
    import importlib
    import pkgutil
    import types
    for info in pkgutil.iter_modules(Q.__path__):
        mod = importlib.import_module(f"{Q.__name__}.{info.name}")
        for name, obj in vars(mod).items():
            if not name.startswith("_") and getattr(obj, "__module__", None) == mod.__name__:
                assert getattr(Q, name) is obj, f"{info.name}.{name} is not re-exported"
                assert name != info.name
        assert not hasattr(Q, info.name) or isinstance(getattr(Q, info.name), types.ModuleType)
    assert all(getattr(Q, n) is f and f.__name__ == n for n, f in Q.QUERIES.items())
    assert {"sessions", "trunk_gait_participants", "with_provenance", "available"} <= set(Q.QUERIES)
