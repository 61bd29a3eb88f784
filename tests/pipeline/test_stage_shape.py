"""Every stage in one shape (issue #45): a frozen typed parameter class whose defaults are the estimators' own
and give the stamped JSON dict unchanged, unknown keys refused naming where, the stamped dict (not a re-serialised
one) behind series keys and stored ``params`` columns, and the reference scoring a separate step that changes no
estimate."""
from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.stages import SessionInput, canonical_json, params_hash, registry
from stridelab.pipeline.stages._shape import params_from_dict, params_to_dict, shaped_stage
from stridelab.warehouse.catalog import Warehouse

from tests.pipeline._lab import run_with, write_lab_session

#: columns the score step fills in rows compute emitted (the reference value beside the estimate)
SCORE_COLUMNS = {"strides": {"stride_length_ref_m"}, "clinical_steps": {"step_length_ref_m"}}
ACCURACY_TABLES = {"accuracy_metrics", "accuracy_pairs"}


@pytest.mark.parametrize("stage", registry(), ids=lambda s: s.name)
def test_every_stage_has_a_frozen_params_class_giving_its_stamped_defaults(stage):
    cls = stage.params_cls
    assert cls is not None and dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen
    d = stage.default_params()
    assert params_from_dict(cls, d) == cls()
    assert canonical_json(params_to_dict(params_from_dict(cls, d))) == canonical_json(d)
    with pytest.raises(ValueError, match=rf"{cls.__name__}: unknown parameter\(s\) no_such_key"):
        stage.compute(SessionInput(root="/nonexistent", session={"session_id": "S"}, recordings=[]),
                      {**d, "no_such_key": 1})


def test_the_defaults_are_the_estimators_own():
    from stridelab.estimators.calibration import CalibrationParams
    from stridelab.estimators.gait import FootParams
    from stridelab.estimators.gait.clinical import ClinicalParams
    from stridelab.estimators.gait.evaluation import EVENT_TOLERANCE_S
    from stridelab.estimators.orientation import DEFAULT_OFFLINE
    from stridelab.estimators.trajectory import DuongSuhParams
    st = {s.name: s.default_params() for s in registry()}
    asdict = lambda p: params_to_dict(p)          # noqa: E731  (tuples as lists, as stamped)
    assert st["gait"]["foot"] == asdict(FootParams()) and st["gait"]["event_tolerance_s"] == EVENT_TOLERANCE_S
    assert st["gait"]["distance_sensors"]["filter"] == asdict(DuongSuhParams(baseline_m=None))
    assert st["clinical"] == asdict(ClinicalParams())
    assert st["calibration"] == {**asdict(CalibrationParams()), "windows": {}}
    assert st["orientation"]["estimator"] == DEFAULT_OFFLINE


def test_a_nested_unknown_key_is_refused_naming_its_place():
    from stridelab.pipeline.stages.gait import GaitParams
    with pytest.raises(ValueError, match=r"GaitParams\.foot\.trajectory: unknown parameter\(s\) nope; known: .*zupt"):
        params_from_dict(GaitParams, {"foot": {"trajectory": {"nope": 1}}})
    p = params_from_dict(GaitParams, {"distance_sensors": {"use": False}, "min_segment_s": 3})
    assert p.distance_sensors.use is False and p.distance_sensors.filter == GaitParams().distance_sensors.filter
    assert p.min_segment_s == 3 and p.foot == GaitParams().foot


def test_a_nested_table_keeps_the_keys_it_does_not_give_at_the_stage_defaults():
    """A manifest that sets one key of a nested table keeps the others as the stage ships them, also where the
    enclosing default differs from the nested class's defaults (the trajectory's own stance detector, the gait
    events' threshold)."""
    import dataclasses

    from stridelab.pipeline.stages.gait import GaitParams
    foot = GaitParams().foot
    p = params_from_dict(GaitParams, {"foot": {"trajectory_zupt": {"window_s": 0.03}, "events": {"refractory_s": 0.2},
                                               "trajectory": {"zupt": {"adapt_ratio": 4.0}}}})
    assert p.foot.trajectory_zupt == dataclasses.replace(foot.trajectory_zupt, window_s=0.03)
    assert p.foot.events == dataclasses.replace(foot.events, refractory_s=0.2)
    assert p.foot.trajectory == dataclasses.replace(foot.trajectory,
                                                    zupt=dataclasses.replace(foot.trajectory.zupt, adapt_ratio=4.0))
    assert params_from_dict(GaitParams, {"foot": {"trajectory_zupt": None}}).foot.trajectory_zupt is None


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """One simulated lab session (calibration + one walking trial, optical reference) through every stage."""
    files, _ = write_lab_session(tmp_path_factory.mktemp("inbox"), distance_sensors=False, optical_reference=True)
    root = tmp_path_factory.mktemp("wh") / "wh"
    mp = pytest.MonkeyPatch()
    try:
        run_with(mp, root, files, registry())
    finally:
        mp.undo()
    with Warehouse.open(root) as wh:
        sid = wh.con.execute("SELECT session_id FROM sessions WHERE kind = 'lab'").fetchone()[0]
    return root, sid


@pytest.mark.slow
@pytest.mark.parametrize("name", ["orientation", "gait", "clinical", "calibration", "joint_angles"])
def test_the_score_step_changes_no_estimate(lab, name):
    """The same stage without its score step: every estimate row and note equal, no accuracy rows."""
    root, sid = lab
    stage = next(s for s in registry() if s.name == name)
    mod = importlib.import_module(f"stridelab.pipeline.stages.{name}")
    bare = shaped_stage(name, stage.version, stage.params_cls, mod.compute, finish=getattr(mod, "finish", None),
                        tables=stage.tables, session_kinds=stage.session_kinds, needs=stage.needs)
    with Warehouse.open(root) as wh:
        inp = runner._session_inputs(wh, sid, stage)
    full, est = stage.compute(inp, stage.default_params()), bare.compute(inp, stage.default_params())
    assert full.status == est.status == "ok" and full.note == est.note
    assert any(full.rows.get(t) for t in ACCURACY_TABLES), f"{name}: the simulated session has references"
    for t in stage.tables:
        if t in ACCURACY_TABLES:
            assert not est.rows.get(t)
            continue
        drop = SCORE_COLUMNS.get(t, set())
        strip = lambda rows: [{k: v for k, v in r.items() if k not in drop} for r in rows]   # noqa: E731
        assert strip(full.rows[t]) == strip(est.rows[t]), t
        assert all(r[c] is None for r in est.rows[t] for c in drop)


@pytest.mark.slow
def test_series_keys_and_params_columns_come_from_the_stamped_dict(lab):
    """An int where the default is a float (a manifest's ``block_s = 3600``): the stored params and the series key
    are those of the dict the runner stamped, as before the stage shape."""
    root, sid = lab
    from stridelab.pipeline.stages import orientation
    with Warehouse.open(root) as wh:
        inp = runner._session_inputs(wh, sid, orientation.STAGE)
    params = {**orientation.STAGE.default_params(), "block_s": 3600}
    out = orientation.STAGE.compute(inp, params)
    rows = out.rows["orientation"]
    assert rows and {r["params"] for r in rows} == {canonical_json(params)}
    assert all(r["series_path"].endswith(f"-{params_hash(params)[:12]}.parquet") for r in rows)
    assert params_hash(params) != params_hash(orientation.STAGE.default_params())
    assert np.isfinite([r["sampling_rate_hz"] for r in rows]).all()


def test_the_study_manifest_is_checked_against_the_params_class(tmp_path, monkeypatch):
    from stridelab.pipeline import config
    d = tmp_path / "s1"
    d.mkdir()
    (d / "study.toml").write_text('[stages.gait]\nmin_segment_s = 3.0\n[stages.gait.distance_sensors]\nuse = false\n'
                                  'fliter = {}\n')
    monkeypatch.setenv("STRIDELAB_STUDIES", str(tmp_path))
    config.study_manifest.cache_clear()
    gait = next(s for s in registry() if s.name == "gait")
    try:
        with pytest.raises(ValueError, match=r"study s1: \[stages\.gait\] GaitParams\.distance_sensors: unknown "
                                             r"parameter\(s\) fliter; known: .*filter"):
            config.stage_params("s1", "gait", gait.default_params())
        (d / "study.toml").write_text('[stages.gait]\nmin_segment_s = 3.0\n[stages.gait.distance_sensors]\n'
                                      'use = false\n')
        config.study_manifest.cache_clear()
        p = config.stage_params("s1", "gait", gait.default_params())
        assert p["min_segment_s"] == 3.0 and p["distance_sensors"] == {"use": False}
        assert params_from_dict(gait.params_cls, p).distance_sensors.filter == gait.params_cls().distance_sensors.filter
    finally:
        config.study_manifest.cache_clear()
