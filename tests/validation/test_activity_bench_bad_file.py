"""``stridelab bench activity`` goes on past a UCI file that cannot be read and lists it with the reason (issue 43:
a bench must never stop on one bad file). Real participant files read in place (symlinks), one broken file."""
from __future__ import annotations

import pytest

from tests.conftest import shared_data


@pytest.mark.slow
@pytest.mark.realdata
def test_activity_bench_lists_a_broken_file_and_scores_the_others(tmp_path):
    from stridelab.validation.bench.activity import run_benchmark
    src = shared_data("uci_chest")
    for n in ("1", "2", "3", "4"):
        (tmp_path / f"{n}.csv").symlink_to(src / f"{n}.csv")
    (tmp_path / "9.csv").write_text("seq,x,y\nnot,a,number\n")
    r = run_benchmark(tmp_path, show_progress=False, speed=False, simulated=0, tuned_rf=False)
    assert [x["file"].rsplit("/", 1)[-1] for x in r["skipped_files"]] == ["9.csv"]
    assert "9.csv" in r["skipped_files"][0]["reason"]
    bas = r["methods"]["default"]["per_participant"]
    assert sorted(bas) == ["1", "2", "3", "4"]
