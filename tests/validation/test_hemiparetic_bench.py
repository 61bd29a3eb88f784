"""Hemiparetic gait bench (issue 18): JSON-safe output even where a class has no matched stride, and the keys the
issue names in ``summary``."""
from __future__ import annotations

import json
from dataclasses import replace

import pytest

from stridelab.estimators.gait import FootParams
from stridelab.validation.bench.hemiparetic import SUMMARY_KEYS, hemiparetic_benchmark


@pytest.mark.slow          # 12 simulated trials through the foot pipeline: ≈ 3 CPU-s
def test_bench_output_is_strict_json_with_the_summary_keys():
    # swing rules off: the severe paretic foot then has no matched stride (stride length MAE undefined)
    r = hemiparetic_benchmark(split="bench", params=replace(FootParams(), swing_events=False), strides=4)
    json.dumps(r, allow_nan=False)
    assert set(r["summary"]) == set(SUMMARY_KEYS)
    assert set(r["by_severity"]) == {"mild", "moderate", "severe"}
    for d in r["by_severity"].values():
        assert {"paretic", "other", "summary"} <= set(d)
