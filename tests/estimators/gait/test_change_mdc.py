"""Between-session MDC95 of a change (stridelab.estimators.gait.clinical.change_mdc95): repeated baselines, published values,
nothing otherwise; never the within-session SEM."""
from __future__ import annotations

import math

import numpy as np
import pytest

from stridelab.estimators.gait.clinical import PUBLISHED_MDC95, change_mdc95, repeated_baseline_sem


def test_repeated_baselines_pooled_within_participant_sd():
    # participant A: 1, 3 (mean 2, SS 2); B: 2, 4, 6 (mean 4, SS 8) -> SEM = sqrt(10 / 3)
    sem, n_p, n_s = repeated_baseline_sem([[1.0, 3.0], [2.0, 4.0, 6.0], [5.0], [np.nan, 7.0]])
    assert (n_p, n_s) == (2, 5)
    assert sem == pytest.approx(math.sqrt(10 / 3))
    m = change_mdc95("cadence_steps_min", baseline=100.0, repeated_baselines=[[1.0, 3.0], [2.0, 4.0, 6.0]])
    assert m.mdc95 == pytest.approx(1.96 * math.sqrt(2) * math.sqrt(10 / 3))
    assert m.source.startswith("repeated baselines (2 participants, 5 sessions)")


@pytest.mark.parametrize("baseline, expected", [(0.25, 0.10), (0.4, 0.15), (0.79, 0.15), (0.8, 0.18), (1.4, 0.18)])
def test_published_gait_speed_by_baseline_band(baseline, expected):
    m = change_mdc95("gait_speed_m_s", baseline=baseline)
    assert m.mdc95 == pytest.approx(expected)
    assert "Lewek & Sykes 2019" in m.source


def test_unknown_measure_or_single_baseline_gives_no_mdc():
    assert math.isnan(change_mdc95("step_time_s", "symmetry_ratio", baseline=1.2).mdc95)
    assert change_mdc95("step_time_s", "symmetry_ratio", baseline=1.2).source == ""
    # one baseline per participant: no between-session error -> falls back to the published value
    m = change_mdc95("gait_speed_m_s", baseline=0.6, repeated_baselines=[[0.6], [0.7]])
    assert m.mdc95 == pytest.approx(0.15)


def test_published_table_is_cited():
    for p in PUBLISHED_MDC95.values():
        assert "doi:" in p.source and p.population
        assert all(v > 0 for _, _, v in p.bands)
