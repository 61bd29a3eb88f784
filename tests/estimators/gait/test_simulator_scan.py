"""``stridelab bench gait --simulator-scan`` on the platform simulator.

The simulator's feet roll over heel and forefoot without impacts (no 16 g heel strike, no under-sampled
transient), so the acceleration-proportional noise c_a, whose purpose is to absorb impacts, should not matter
there: both settings give accurate strides and neither is clearly better. c_a = 0.3 rests on the gaitmap walk
(docs/gait.md)."""
from __future__ import annotations

import pytest


@pytest.mark.slow
def test_simulator_scan_strides_are_accurate_and_c_a_is_neutral_without_impacts():
    from stridelab.validation.bench.gait import simulator_scan
    r = simulator_scan(participants=1, acc_noise_rel=(0.0, 0.3))["by_acc_noise_rel"]
    assert r["0.3"]["strides"] > 40 and r["0.0"]["strides"] == r["0.3"]["strides"]
    assert r["0.0"]["stride_length_mae_m"] < 0.02 and r["0.3"]["stride_length_mae_m"] < 0.02
    assert abs(r["0.3"]["stride_length_mae_m"] - r["0.0"]["stride_length_mae_m"]) < 0.003
