"""``stridelab bench gait --simulator-scan``: c_a chosen on the platform simulator, not on the evaluation walk."""
from __future__ import annotations

import pytest


@pytest.mark.slow
def test_simulator_scan_prefers_acceleration_proportional_noise():
    from pipeline.bench.gait import simulator_scan
    r = simulator_scan(participants=1, acc_noise_rel=(0.0, 0.3))["by_acc_noise_rel"]
    assert r["0.3"]["strides"] > 40
    assert r["0.3"]["stride_length_mae_m"] < r["0.0"]["stride_length_mae_m"] < 0.06
