"""``stridelab bench gait --voisard`` goes on past a trial that cannot be read (listed with the reason naming the
file) and scores a trial whose packet counter repeats (issue 43: the whole bench used to stop with "packet counter
repeats a value" without naming the file). Two real trials (symlinked, read in place), one copy of a real trial with
one counter value repeated (written to the test's temporary folder only), one trial with a broken file."""
from __future__ import annotations

import pytest

from tests.conftest import shared_data


@pytest.mark.slow
@pytest.mark.realdata
def test_voisard_bench_lists_the_bad_trial_and_scores_the_rest(tmp_path):
    from stridelab.validation.bench.gait import voisard_benchmark
    src = shared_data("voisard_gait")
    d = tmp_path / "voisard"
    d.mkdir()
    for name in ("3-1", "6-2"):
        for f in src.glob(f"{name}[._]*"):
            (d / f.name).symlink_to(f)
    # 6-3: the left foot's counter repeats one value (row kept, values differ), as in the held-back trial
    for f in src.glob("6-3[._]*"):
        (d / f.name).symlink_to(f)
    (d / "6-3_lf.txt").unlink()
    lines = (src / "6-3_lf.txt").read_text().splitlines()
    cols = lines[500].split("\t")
    cols[0] = lines[499].split("\t")[0]
    lines[500] = "\t".join(cols)
    (d / "6-3_lf.txt").write_text("\n".join(lines) + "\n")
    # 9-1: a broken right-foot file
    for f in src.glob("9-1[._]*"):
        (d / f.name).symlink_to(f)
    (d / "9-1_rf.txt").unlink()
    (d / "9-1_rf.txt").write_text("Acquisition frequency: 100 Hz\nPacketCounter\tAcc_X\n")
    r = voisard_benchmark(d, show_progress=False)
    assert [s["trial"] for s in r["skipped_files"]] == ["9-1"]
    assert "9-1_rf.txt" in r["skipped_files"][0]["reason"]
    assert len(r["warnings"]) == 1 and "6-3_lf.txt" in r["warnings"][0] and "repeats" in r["warnings"][0]
    for block in ("shipped_defaults", "cross_validated", "in_sample"):
        for k in ("ic_sensitivity", "ic_precision", "ic_timing_mae_ms", "tc_sensitivity", "tc_precision",
                  "tc_timing_mae_ms"):
            assert k in r[block]
    assert r["shipped_defaults"]["ic_tp"] > 60                  # 3 trials x 2 feet x ~10-18 heel strikes scored
    assert sorted(r["per_subject"]) == ["3", "6"]
