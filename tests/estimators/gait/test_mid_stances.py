"""``mid_stances``: the sample of least angular rate in each stance run, the points strides are cut at."""
from __future__ import annotations

import numpy as np

from stridelab.estimators.gait import mid_stances


def test_one_mid_stance_per_run_at_the_least_angular_rate():
    stance = np.zeros(20, bool)
    stance[2:6] = stance[10:11] = stance[15:20] = True          # three runs, one of a single sample, one at the end
    w = np.full(20, 5.0)
    w[[4, 10, 17]] = [0.1, 3.0, 0.2]
    gyr = np.column_stack([w * 0.6, -w * 0.8, np.zeros(20)])    # |ω| = w
    assert mid_stances(stance, gyr).tolist() == [4, 10, 17]
    assert mid_stances(np.zeros(20, bool), gyr).dtype == np.int64 and len(mid_stances(np.zeros(20, bool), gyr)) == 0
