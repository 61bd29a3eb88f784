"""Window-model refinement of the rule timeline (stridelab.estimators.activity.window_model) and the shipped model."""
import json

import numpy as np
import pytest

from stridelab.estimators.activity._types import DOWN, LEVEL, LYING, NON_WEAR, SITTING, STANDING, UP
from stridelab.estimators.activity.window_model import FEATURE_SETS, WindowModel, merge_window_posterior
from tests.conftest import shared_data


def _p(k, n):
    pr = np.full((n, 4), 0.02)
    pr[:, k] = 0.94
    return pr


def test_gates_keep_lying_nonwear_and_rule_sitting_and_forbid_motion_in_still_windows():
    rule = np.array([LYING] * 10 + [NON_WEAR] * 10 + [SITTING] * 10 + [STANDING] * 10, dtype=np.int8)
    gait = np.zeros(4, bool)
    lean = np.zeros(4)
    # the model says stairs everywhere: nothing may move (no rule bout, no gait-like window)
    out = merge_window_posterior(rule, _p(3, 4), gait, lean)
    assert out[:30].tolist() == rule[:30].tolist()
    assert (out[30:] == STANDING).all()
    # the model says sitting: a rule-standing still window becomes sitting, rule sitting stays sitting
    out = merge_window_posterior(rule, _p(0, 4), gait, lean)
    assert (out[20:40] == SITTING).all() and out[:20].tolist() == rule[:20].tolist()
    # the model says standing: rule sitting stays sitting
    out = merge_window_posterior(rule, _p(1, 4), gait, lean)
    assert (out[20:30] == SITTING).all()


def test_motion_only_where_the_chest_moves():
    rule = np.array([STANDING] * 4 + [LEVEL] * 6 + [STANDING] * 10, dtype=np.int8)
    # window 0: rule bout in seconds 4-9 -> model stairs applies there only (lean > 4 deg: up)
    out = merge_window_posterior(rule, _p(3, 2), np.array([False, False]), np.array([8.0, 0.0]))
    assert out[:4].tolist() == [STANDING] * 4 and (out[4:10] == UP).all() and (out[10:] == STANDING).all()
    # window 1 gait-like without a rule bout: the whole window walks when the model says walking
    out = merge_window_posterior(rule, _p(2, 2), np.array([False, True]), np.array([0.0, 0.0]))
    assert (out[4:10] == LEVEL).all() and (out[10:20] == LEVEL).all()
    # stairs found by the rules keep their direction
    rule2 = np.array([DOWN] * 10, dtype=np.int8)
    out = merge_window_posterior(rule2, _p(3, 1), np.array([True]), np.array([20.0]))
    assert (out == DOWN).all()


def _merge_one_window_at_a_time(second_class, proba, gait_like, lean_walk_deg, stairs_lean_deg=4.0):
    """The gates of the module docstring written out second by second (the reference for the array form)."""
    sec = np.asarray(second_class).astype(np.int8).copy()
    for i in range(min(proba.shape[0], sec.size // 10)):
        s = sec[i * 10:(i + 1) * 10]
        rule = s.copy()
        free = (rule != LYING) & (rule != NON_WEAR)
        walk = free & np.isin(rule, (LEVEL, UP, DOWN))
        dyn = walk if walk.any() else (free if gait_like[i] else np.zeros_like(free))
        k = int(np.argmax(proba[i]))
        cls = (SITTING, STANDING, LEVEL)[k] if k <= 2 else (UP if lean_walk_deg[i] > stairs_lean_deg else DOWN)
        posture = SITTING if proba[i, 0] > proba[i, 1] else STANDING
        for j in np.flatnonzero(free):
            if dyn[j]:
                s[j] = rule[j] if cls in (UP, DOWN) and rule[j] in (UP, DOWN) else cls
            elif rule[j] != SITTING:
                s[j] = posture
    return sec


@pytest.mark.parametrize("seed", range(6))
def test_merge_equals_the_second_by_second_gates(seed):
    rng = np.random.default_rng(seed)
    n_win = 300
    # rule timelines of runs of a few seconds, so windows mix classes; ties in the posterior included
    codes = np.array([SITTING, STANDING, LEVEL, UP, DOWN, LYING, NON_WEAR])
    runs = rng.choice(codes, size=n_win * 3, p=[0.25, 0.25, 0.15, 0.05, 0.05, 0.15, 0.10])
    sec = np.repeat(runs, rng.integers(1, 8, runs.size))[: n_win * 10 + 7]       # 7 s after the last window
    proba = rng.dirichlet(np.ones(4), size=n_win)
    proba[::17] = 0.25
    gait = rng.random(n_win) < 0.3
    lean = rng.normal(4.0, 3.0, n_win)
    lean[::23] = np.nan
    got = merge_window_posterior(sec, proba, gait, lean)
    np.testing.assert_array_equal(got, _merge_one_window_at_a_time(sec, proba, gait, lean))
    assert got.dtype == np.int8 and got.shape == sec.shape


def _model(n_feat, **kw):
    rng = np.random.default_rng(0)
    return WindowModel(feature_set="no_clusters", context=(6,), mean=np.zeros(n_feat), scale=np.ones(n_feat),
                       coef=rng.normal(size=(4, n_feat)), intercept=np.zeros(4), **kw)


def test_model_file_roundtrip_shape_check_and_clipping():
    n = len(FEATURE_SETS["no_clusters"]) * 2
    m = _model(n, lo=-np.ones(n), hi=np.ones(n), trained_on=("1", "2"))
    m2 = WindowModel.from_dict(json.loads(json.dumps(m.to_dict())))
    x = np.random.default_rng(1).normal(size=(5, n)) * 5
    np.testing.assert_allclose(m2.predict_proba(x), m.predict_proba(x))
    np.testing.assert_allclose(m.predict_proba(x).sum(axis=1), 1.0)
    # clipped to [lo, hi]: far outside behaves like the bound
    np.testing.assert_allclose(m.predict_proba(x * 100), m.predict_proba(np.clip(x * 100, -1, 1)))
    assert m2.trained_on == ("1", "2")
    bad = m.to_dict()
    bad["coef"] = bad["coef"][:2]
    with pytest.raises(ValueError, match="do not match feature set"):
        WindowModel.from_dict(bad)


def test_missing_model_file_is_one_clear_line(tmp_path):
    from stridelab.pipeline.activity_model import load_model
    with pytest.raises(ValueError, match="not a window-model file.*--fit-model"):
        load_model(tmp_path / "nope.json")


@pytest.mark.realdata
def test_shipped_model_is_reproduced_by_refitting_its_design_on_its_participants():
    """The shipped file is what the documented fit gives: the final design refitted on the same UCI
    participants (deterministic newton-cg) reproduces its coefficients."""
    from stridelab.pipeline.activity_model import design_x, fit_model, load_model, raw_features
    from stridelab.validation.bench.activity import WINDOW_S, window_labels
    from stridelab.pipeline.formats.uci_chest import load_uci_participant
    d = shared_data("uci_chest")
    shipped = load_model()
    assert shipped.trained_on == tuple(str(k) for k in range(1, 9))
    xs, ys = [], []
    design = {"feature_set": shipped.feature_set, "context": shipped.context}
    for q in shipped.trained_on:
        u = load_uci_participant(d / f"{q}.csv")
        wf = raw_features(u.acc, u.sampling_rate_hz)
        w = int(round(WINDOW_S * u.sampling_rate_hz))
        y = window_labels(u.labels, w, min(wf.x.shape[0], u.labels.size // w))
        xs.append(design_x(wf, design)[: y.size])
        ys.append(y)
    m = fit_model(xs, ys, {**design, "C": shipped.C})
    np.testing.assert_allclose(m.coef, shipped.coef, atol=1e-6)
    np.testing.assert_allclose(m.intercept, shipped.intercept, atol=1e-6)
