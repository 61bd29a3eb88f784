"""``stridelab bench gait`` on the gaitmap example walk (real data; skipped without ../shared/data)."""
from __future__ import annotations

import pytest

from tests.conftest import shared_data


@pytest.mark.realdata
def test_bench_gait_on_gaitmap_example():
    from pipeline.bench.gait import run_benchmark
    res = run_benchmark(shared_data("gaitmap_example"), show_progress=False, speed=False)
    for k in ("stride_length_mae_m", "ic_timing_mae_ms", "tc_timing_mae_ms", "ic_sensitivity", "ic_precision",
              "tc_sensitivity", "tc_precision"):
        assert k in res and k in res["per_foot"]["left"] and k in res["per_foot"]["right"]
    # measured (docs/gait.md): 2.5 cm, IC 7 ms, TC 21 ms, Se/Pr >= 98 %; guard against regressions
    assert res["stride_length_mae_m"] < 0.03
    assert res["ic_timing_mae_ms"] < 20 and res["tc_timing_mae_ms"] < 25
    assert res["tc_sensitivity"] == 1.0 and res["tc_precision"] == 1.0
    assert res["ic_sensitivity"] >= 0.98 and res["ic_precision"] >= 0.98
