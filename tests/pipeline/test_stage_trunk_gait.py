"""The trunk-gait stage (first stage in the shape of pipeline/stages/_shape.py) through the real runner: simulated
lower-back recordings (the simulator's own gait model) as MCAP files -> walking_bouts, daily_gait_outcomes,
accuracy rows against reference contacts; the stage shape's contracts."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from stridelab.pipeline.stages import SessionInput
from stridelab.pipeline.stages import trunk_gait as tg
from stridelab.pipeline.stages._shape import StageContext, params_from_dict, params_to_dict, shaped_stage
from tests.pipeline._lab import df as _df
from tests.pipeline._lab import run_with

pytestmark = pytest.mark.slow

REG = [tg.STAGE]


def _flip(imu):
    """The same sensor mounted upside down: 180° about its y axis (x and z negated)."""
    s = np.array([-1.0, 1.0, -1.0])
    return replace(imu, acc=imu.acc * s, gyr=imu.gyr * s)


@pytest.fixture(scope="module")
def warehouse(tmp_path_factory):
    from stridelab.pipeline.formats.mcap_write import write_recording
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.simulator import simulate_chest_day, simulate_lab_session, study_participants
    m = load_manifest(DEFAULT_MANIFEST).with_free_living_hours(1.0)
    m = replace(m, lab=replace(m.lab, walking_trials=1, lower_back=True, distance_sensors=False,
                               optical_reference=False), free_living=replace(m.free_living, lower_back=True))
    inbox = tmp_path_factory.mktemp("inbox")
    p = study_participants(m, 4)
    files, truth = [], {}
    for rec, tr in simulate_lab_session(m, p[2], 2):
        if rec.metadata["trial"] == "calibration":
            continue
        # the simulator's true contacts of the first half of the walking as a labelled reference with one reference
        # walking bout around them (as the Mobilise-D importer writes INDIP's); the second half is walking the
        # reference leaves out, where contacts are not scored
        ics = sorted((t, side) for side in ("left", "right") for t in tr.events[side]["IC"])
        ics = ics[:len(ics) // 2]
        for t, side in ics:
            rec.events.append({"t_ns": int(tr.t_ns[0] + round(t * 1e9)), "type": "IC", "side": side,
                               "label": "INDIP", "placement": "lower_back"})
        rec.events.append({"t_ns": int(tr.t_ns[0] + round(ics[0][0] * 1e9)),
                           "end_ns": int(tr.t_ns[0] + round(ics[-1][0] * 1e9)), "type": "walking_bout",
                           "label": "INDIP", "placement": "lower_back"})
        truth["lab"] = tr
        truth["ref_ic_s"] = np.array([t for t, _ in ics])
        files.append(write_recording(rec, inbox / f"{rec.name}.mcap"))
    rec, _ = simulate_chest_day(m, p[0], 0)
    files.append(write_recording(rec, inbox / f"{rec.name}.mcap"))
    rec, _ = simulate_chest_day(m, p[1], 1)
    rec.imu["lower_back"] = _flip(rec.imu["lower_back"])
    del rec.imu["chest"]
    files.append(write_recording(rec, inbox / f"{rec.name}.mcap"))
    root = tmp_path_factory.mktemp("wh") / "wh"
    mp = pytest.MonkeyPatch()
    try:
        run_with(mp, root, files, REG)
    finally:
        mp.undo()
    return root, truth


def test_bouts_on_lab_and_home_sessions(warehouse):
    root, truth = warehouse
    b = _df(root, "SELECT b.*, s.kind, s.participant_id FROM walking_bouts b JOIN sessions s USING (session_id)")
    assert set(b["participant_id"]) == {"P001", "P002", "P003"}
    assert set(b["placement"]) == {"lower_back"}          # preferred over the chest on the home days
    assert (b["end_ns"] > b["start_ns"]).all() and (b["duration_s"] > 0).all()
    assert (b["height_source"] == "given").all()           # the simulator writes height_m
    lab = b[b["kind"] == "lab"]
    tr = truth["lab"]
    # the bout lies inside the trial and covers most of its true contacts
    ic = np.sort(np.concatenate([tr.events[s]["IC"] for s in ("left", "right")]))
    t0 = int(tr.t_ns[0])
    assert lab["start_ns"].min() >= t0 and lab["end_ns"].max() <= int(tr.t_ns[-1])
    covered = ((t0 + ic * 1e9 >= lab["start_ns"].min()) & (t0 + ic * 1e9 <= lab["end_ns"].max())).mean()
    assert covered > 0.8


def test_daily_outcomes_recomputable_from_bouts(warehouse):
    root, _ = warehouse
    d = _df(root, "SELECT d.*, s.participant_id FROM daily_gait_outcomes d JOIN sessions s USING (session_id)")
    b = _df(root, "SELECT b.*, s.participant_id FROM walking_bouts b JOIN sessions s USING (session_id) "
                  "WHERE s.kind = 'free_living'")
    assert set(d["participant_id"]) == {"P001", "P002"} and len(d) == 2     # one hour of a day each
    for _, r in d.iterrows():
        mine = b[b["participant_id"] == r["participant_id"]]
        assert r["n_bouts"] == len(mine)
        assert r["walking_time_s"] == pytest.approx(mine["duration_s"].sum())
        long = mine[mine["duration_s"] > 10.0]
        assert r["n_bouts_over_10s"] == len(long)
        if len(long):
            assert r["speed_median_m_s"] == pytest.approx(np.median(long["walking_speed_m_s"]))
        assert r["n_bouts_10_30s"] == ((mine["duration_s"] >= 10) & (mine["duration_s"] < 30)).sum()
        assert 0.95 * 3600 < r["recorded_s"] <= 3600 + 1


def test_upside_down_sensor_flagged(warehouse):
    root, _ = warehouse
    b = _df(root, "SELECT b.flags FROM walking_bouts b JOIN sessions s USING (session_id) "
                  "WHERE s.participant_id = 'P002'")
    assert len(b) and b["flags"].str.contains("upside_down").all()
    runs = _df(root, "SELECT note FROM stage_runs WHERE stage = 'trunk_gait' AND note LIKE '%upside down%'")
    assert len(runs) >= 1


def test_accuracy_rows_against_labelled_contacts(warehouse):
    root, truth = warehouse
    m = _df(root, "SELECT * FROM accuracy_metrics WHERE stage = 'trunk_gait'").set_index("metric")
    assert set(m["estimator"]) == {"trunk_gait vs INDIP"}
    n_ref = len(truth["ref_ic_s"])
    assert m.loc["n_reference_ic", "value"] == n_ref
    pairs = _df(root, "SELECT * FROM accuracy_pairs WHERE stage = 'trunk_gait' AND quantity = 'IC'")
    # sensitivity = matched pairs / reference contacts, as the one scorer counts them
    assert m.loc["ic_sensitivity", "value"] == pytest.approx(len(pairs) / n_ref)
    assert m.loc["ic_timing_mae_ms", "value"] == pytest.approx(
        1000 * np.abs(pairs["estimate"] - pairs["reference"]).mean())
    assert (np.abs(pairs["estimate"] - pairs["reference"]) <= 0.25).all()
    # contacts scored inside the reference bout ± 0.25 s, as the bench scores them: the detections of the unreferenced
    # second half of the walking are no extra contacts (over the whole recording precision would be about 0.5)
    assert m.loc["ic_precision", "value"] >= 0.9
    # the free-living days have no labelled reference: no accuracy rows for them
    sess = _df(root, "SELECT DISTINCT a.session_id, s.kind FROM accuracy_metrics a JOIN sessions s USING (session_id)")
    assert set(sess["kind"]) == {"lab"}


# ---- the stage shape ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Inner:
    gain: float = 1.0


@dataclass(frozen=True)
class _P:
    """window_s: s."""
    window_s: float = 2.0
    names: tuple[str, ...] = ("a",)
    inner: _Inner = _Inner()


def test_params_round_trip_and_unknown_keys_refused():
    d = params_to_dict(_P(names=("a", "b"), inner=_Inner(3.0)))
    assert d == {"window_s": 2.0, "names": ["a", "b"], "inner": {"gain": 3.0}}
    assert params_from_dict(_P, d) == _P(names=("a", "b"), inner=_Inner(3.0))
    with pytest.raises(ValueError, match="unknown parameter"):
        params_from_dict(_P, {"window": 1.0})
    assert params_from_dict(tg.TrunkGaitStageParams, tg.STAGE.default_params()) == tg.TrunkGaitStageParams()


def _inp(sensors):
    rec = {"content_hash": "h", "trial": "t", "start_ns": 0, "end_ns": 10, "sensors": sensors, "metadata": {}}
    return SessionInput(root="/nonexistent", session={"session_id": "s", "kind": "lab"}, recordings=[rec],
                        events=[{"t_ns": 5, "end_ns": None, "type": "IC", "side": "left", "placement": None,
                                 "label": "INDIP", "payload": '{"t_ns": 5, "type": "IC", "extra": 1.5}'}])


def test_shaped_stage_skips_without_declared_input_and_refuses_undeclared_tables():
    calls = []
    st = shaped_stage("demo", "1", _P, lambda ctx, p: calls.append(p), placements=("lower_back",),
                      tables=("walking_bouts",), session_kinds=("lab",))
    out = st.compute(_inp({"foot_left": {"imu": {}}}), st.default_params())
    assert out.status == "skipped" and "no lower_back IMU (session has foot_left)" in out.note and not calls
    ctx = StageContext(_inp({}), ("walking_bouts",), ("lower_back",))
    with pytest.raises(RuntimeError, match="does not declare"):
        ctx.emit("strides", [{}])
    ev = ctx.events("IC", "INDIP")
    assert ev[0]["extra"] == 1.5 and ev[0]["side"] == "left" and "payload" not in ev[0]
    assert ctx.events("IC", "Stereophoto") == []


def test_day_by_day_reading_gives_the_same_rows(warehouse):
    """Recordings longer than ``day_pieces_above_s`` are read one local day at a time (a week is never held at
    once); on an hour inside one day that path gives the rows of the whole-recording path."""
    from stridelab.pipeline.runner import _session_inputs
    from stridelab.warehouse.catalog import Warehouse
    root, _ = warehouse
    sid = _df(root, "SELECT session_id FROM sessions WHERE participant_id = 'P001' AND kind = 'free_living'")
    with Warehouse.open(root) as wh:
        inp = _session_inputs(wh, sid["session_id"][0], tg.STAGE)
    whole = tg.STAGE.compute(inp, tg.STAGE.default_params())
    pieces = tg.STAGE.compute(inp, dict(tg.STAGE.default_params(), day_pieces_above_s=60.0))
    assert whole.rows["walking_bouts"] and whole.rows["walking_bouts"] == pieces.rows["walking_bouts"]
    assert whole.rows["daily_gait_outcomes"] == pieces.rows["daily_gait_outcomes"]
