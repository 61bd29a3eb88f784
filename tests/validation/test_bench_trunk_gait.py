"""``stridelab bench trunk-gait`` on a few real Voisard trials plus one broken copy: the broken file is listed with
its reason and the bench goes on; the blocks carry the six keys (Voisard stride length against its foot-INS
reference); mobgap absent -> anchor null with a reason."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.conftest import shared_data

pytestmark = [pytest.mark.realdata, pytest.mark.slow]


def test_bench_skips_a_broken_file_and_reports_every_block(tmp_path):
    from stridelab.validation.bench.trunk_gait import KEYS, run_benchmark
    src = shared_data("voisard_gait")
    for name in ("1-1", "2-1"):                       # a temporary copy (never into the repository: AGPL data)
        for suffix in (".json", "_lf.txt", "_rf.txt", "_lb.txt"):
            shutil.copy(src / f"{name}{suffix}", tmp_path / f"{name}{suffix}")
    lines = (tmp_path / "2-1_lb.txt").read_text().splitlines()
    # a data row cut short (a truncated write): still broken, unlike a repeated packet counter, which the reader
    # keeps with a warning since the events branch (pipeline/formats/xsens_mt.py policy)
    lines[10] = "\t".join(lines[10].split("\t")[:3])
    (tmp_path / "2-1_lb.txt").write_text("\n".join(lines) + "\n")
    res = run_benchmark(tmp_path, None, mobgap_python=tmp_path / "no-such-python", anchor=True, day=False,
                        show=False)
    assert [Path(f["file"]).name for f in res["failed_files"]] == ["2-1_lb.txt"]
    assert "data line" in res["failed_files"][0]["reason"] and "fields" in res["failed_files"][0]["reason"]
    assert res["anchor"] is None and "make .venv-mobgap" in res["anchor_reason"]
    for blk in ("shipped_defaults", "cross_validated", "in_sample"):
        assert set(KEYS) <= set(res[blk]["voisard"]) and set(KEYS) <= set(res[blk]["overall"])
        # Voisard's spatial reference comes from its foot sensors (foot INS), said so in the output
        assert 0 <= res[blk]["voisard"]["stride_length_mae_m"] < 0.3
        assert 0 <= res[blk]["voisard"]["walking_speed_mae_m_s"] < 0.3
    assert "foot INS" in res["spatial_references"]["voisard"]
    assert res["voisard_foot_reference"]["trials"] == 1 and res["voisard_foot_reference"]["strides"] > 10
    s = res["shipped_defaults"]["voisard"]
    assert s["ic_sensitivity"] > 0.8 and s["ic_precision"] > 0.8 and s["ic_timing_mae_ms"] < 50


def test_bench_recomputes_bout_values_as_the_estimator_does():
    # the spatial grid recomputes the bouts' stride length and speed from one run's strides (respatial); with the
    # shipped options it must give the estimator's own bout values, and the other options must change them
    import dataclasses

    import numpy as np

    from stridelab.estimators.trunk_gait import TrunkGaitParams
    from stridelab.validation.bench.trunk_gait import load_voisard, respatial, run_ours
    rec = load_voisard(shared_data("voisard_gait"), [], 1, foot_reference=False)[0]
    p = TrunkGaitParams()
    det = run_ours(rec, p)
    assert len(det.bouts["start_s"]) >= 1
    same = respatial(det, p.bout_average, p.bout_strides, p.speed_method, p.sl_max_tilt_deg)
    np.testing.assert_allclose(same.bouts["stride_length_m"], det.bouts["stride_length_m"])
    np.testing.assert_allclose(same.bouts["walking_speed_m_s"], det.bouts["walking_speed_m_s"])
    other = run_ours(rec, dataclasses.replace(p, bout_average="mean", speed_method="stride"))
    re = respatial(det, "mean", p.bout_strides, "stride")
    np.testing.assert_allclose(re.bouts["stride_length_m"], other.bouts["stride_length_m"])
    np.testing.assert_allclose(re.bouts["walking_speed_m_s"], other.bouts["walking_speed_m_s"])
    assert not np.allclose(re.bouts["walking_speed_m_s"], det.bouts["walking_speed_m_s"])


def test_ic_score_gives_the_ic_loss_of_the_full_score_at_every_offset():
    # the IC grid scores contacts alone (ic_score, no bout matching); its loss must equal the full score's
    import numpy as np

    from stridelab.estimators.trunk_gait import TrunkGaitParams
    from stridelab.validation.bench.trunk_gait import ic_loss, ic_score, load_voisard, run_ours, score
    recs = load_voisard(shared_data("voisard_gait"), [], 2, foot_reference=False)
    dets = [run_ours(r, TrunkGaitParams()) for r in recs]
    losses = []
    for o in (-0.2, -0.05, 0.0, 0.1):
        full, fast = score(recs, dets, offset_s=o), ic_score(recs, dets, offset_s=o)
        assert {k: full[k] for k in fast} == fast
        losses.append(ic_loss(fast))
        assert ic_loss(fast) == ic_loss(full)
    assert len(set(np.round(losses, 6))) == len(losses)      # the offset moves the loss: the check can fail
