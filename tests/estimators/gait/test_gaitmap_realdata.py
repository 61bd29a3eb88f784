"""``stridelab bench gait`` on the gaitmap example walk (real data; skipped without ../shared/data)."""
from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import shared_data


@pytest.mark.realdata
def test_bench_gait_on_gaitmap_example():
    from stridelab.validation.bench.gait import run_benchmark
    res = run_benchmark(shared_data("gaitmap_example"), show_progress=False, speed=False)
    for k in ("stride_length_mae_m", "ic_timing_mae_ms", "tc_timing_mae_ms", "ic_sensitivity", "ic_precision",
              "tc_sensitivity", "tc_precision"):
        assert k in res and k in res["per_foot"]["left"] and k in res["per_foot"]["right"]
    # issue #4 targets (stride length <= 2 cm, IC/TC Se = Pr = 100 %, IC and TC timing <= 20 ms). The IC timing
    # target is on this walk's marker-derived IC, the pitch maximum (``ic_pitch_max``); the shipped IC is moved into
    # the loading rotation (H1, Voisard's heel-strike convention, issue 43): ~25 ms after it here, reported beside it
    assert res["stride_length_mae_m"] <= 0.02
    assert res["ic_pitch_max_timing_mae_ms"] <= 20 and res["tc_timing_mae_ms"] <= 20
    assert res["ic_timing_mean_ms"] > res["ic_pitch_max_timing_mean_ms"]
    # the toe-off refinement (T1) must help each foot on its own, not just the pooled figure
    for side in ("left", "right"):
        pf = res["per_foot"][side]
        assert pf["tc_timing_mae_ms"] <= 20 and pf["tc_timing_mae_ms"] < pf["tc_pitch_min_timing_mae_ms"], (side, pf)
    for tol in ("0.1", "0.5"):
        ov = res["by_tolerance"][tol]["overall"]
        for k in ("ic_sensitivity", "ic_precision", "tc_sensitivity", "tc_precision"):
            assert ov[k] == 1.0, (tol, k, ov[k])
    # unscorable detections are few (one pivot step of the left foot in the turn is not labelled by the reference)
    assert res["ic_unannotated"] <= 2 and res["tc_unannotated"] <= 2


def _foot(markers, strides):
    from stridelab.pipeline.formats.gaitmap import GaitmapFoot
    return GaitmapFoot(side="left", gyr=np.zeros((1, 3)), acc=np.zeros((1, 3)), markers=markers, strides=strides)


def test_unannotated_spans_only_where_the_foot_stands_still_in_a_reference_swing():
    from stridelab.validation.bench.gait import unannotated_spans
    fs, mfs = 200.0, 100.0
    t = np.arange(600) / mfs
    # heel and toe move forward at 1 m/s except a still period 2.0-2.5 s (inside the 2nd reference swing)
    x = np.cumsum(np.where((t >= 2.0) & (t < 2.5), 0.0, 1.0)) / mfs
    heel = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.05)])
    toe = heel + [0.25, 0, 0]
    # strides: start, end, ic, tc (IMU samples at 200 Hz); swings 0.5-1.5 s, 1.8-2.9 s, 3.5-4.5 s
    strides = np.array([[0, 400, 300, 100, 0, 0], [400, 700, 580, 360, 400, 300], [700, 1000, 900, 700, 700, 580]])
    spans = unannotated_spans(_foot({"FCC": heel, "TOE": toe}, strides), fs, mfs)
    assert spans.tolist() == [[360, 580]]
    # a still period shorter than STILL_MIN_S is not a foot placement
    x2 = np.cumsum(np.where((t >= 2.0) & (t < 2.1), 0.0, 1.0)) / mfs
    heel2 = np.column_stack([x2, np.zeros_like(x2), np.full_like(x2, 0.05)])
    assert len(unannotated_spans(_foot({"FCC": heel2, "TOE": heel2 + [0.25, 0, 0]}, strides), fs, mfs)) == 0
