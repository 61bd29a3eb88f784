"""The trunk-gait bench's timing diagnosis by contact kind (``ic_timing_by_kind``) on hand-made contacts of known
error."""
from __future__ import annotations

import numpy as np
import pytest


def test_timing_by_kind_splits_the_errors_by_how_each_contact_was_found():
    from stridelab.estimators.trunk_gait._icd import IC_KINDS
    from stridelab.validation.bench.trunk_gait import Det, Rec, ic_timing_by_kind
    ref = np.arange(1.0, 6.01, 0.5)                                  # 11 reference contacts, the last one at 6.0
    k = {n: IC_KINDS.index(n) for n in IC_KINDS}
    # 8 steady peaks 10 ms late, a gap fill 60 ms late (at 3.5 s), the last peak before the closing step 40 ms late,
    # the closing step by the rhythm 80 ms late; the reference contact at 2.0 s is missed; an extra fill at 7.0 s
    det = np.r_[ref[:2] + 0.01, ref[3:5] + 0.01, ref[5] + 0.06, ref[6:9] + 0.01, ref[9] + 0.04, ref[10] + 0.08, 7.0]
    kinds = np.array([0, 0, 0, 0, k["gap_fill"], 0, 0, 0, 0, k["closing_rhythm"], k["gap_fill"]], np.int8)
    rec = Rec(name="x", dataset="voisard", group="g", trial_group="x", acc=np.zeros((1, 3)), gyr=np.zeros((1, 3)),
              fs=100.0, height_m=None, leg_length_m=None, ref_ic_s=ref, ref_bouts={}, window_s=(0.0, 10.0))
    out = ic_timing_by_kind([rec], [Det(ic_s=det, bouts={}, ic_kind=kinds)])["voisard"]
    assert out["missed"] == 1
    b = out["by_kind"]
    assert b["peak"]["matched"] == 7 and b["peak"]["timing_mae_ms"] == pytest.approx(10.0)
    assert b["peak_before_closing"]["matched"] == 1 and b["peak_before_closing"]["timing_bias_ms"] == pytest.approx(40.0)
    assert b["gap_fill"]["matched"] == 1 and b["gap_fill"]["extra"] == 1
    assert b["gap_fill"]["timing_mae_ms"] == pytest.approx(60.0)
    assert b["closing_rhythm"]["timing_bias_ms"] == pytest.approx(80.0)
    # the shares add up to the timing MAE of all matched contacts
    assert sum(v["share_of_timing_mae_ms"] for v in b.values()) == pytest.approx((70 + 40 + 60 + 80) / 10, abs=0.05)
    # an offset moves every contact: with -10 ms the steady peaks are on time
    shifted = ic_timing_by_kind([rec], [Det(ic_s=det, bouts={}, ic_kind=kinds)], offsets=[-0.01])["voisard"]
    assert shifted["by_kind"]["peak"]["timing_mae_ms"] == pytest.approx(0.0, abs=1e-6)
