"""Exit codes of `stridelab run` / `stridelab ingest`, one test per outcome of the table in docs/operations.md."""
from __future__ import annotations

import re

import pytest

from stridelab.pipeline.formats.mcap_write import write_recording
from tests.conftest import PROJECT_ROOT
from tests.corpus import small_recording
from tests.pipeline.test_runner import cli
from stridelab.warehouse.lock import RunLock


def _inbox(d, study="testing", n=1, seconds=5.0):
    d.mkdir(parents=True, exist_ok=True)
    return [write_recording(small_recording(seconds=seconds, seed=i, session=f"{study}-S{i}", study=study,
                                            trial="walk-1"), d / f"{study}_{i}.mcap") for i in range(n)]


def test_the_table_in_the_docs_lists_the_three_codes():
    text = (PROJECT_ROOT / "docs" / "operations.md").read_text()
    section = re.search(r"^### Exit codes\n(.*?)(?=^#)", text, re.M | re.S)       # the section alone: other tables
    assert section, "docs/operations.md has no '### Exit codes' section"          # of the page number their rows too
    rows = re.findall(r"^\| (\d) \|", section.group(1), re.M)
    assert rows == ["0", "1", "2"]


@pytest.mark.slow
def test_all_ok_exits_0_and_a_second_run_with_nothing_to_do_too(tmp_path):
    _inbox(tmp_path / "inbox")
    args = ("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1",
            "--reports", tmp_path / "reports")
    r = cli(*args)
    assert r.returncode == 0, r.stderr
    assert list((tmp_path / "reports").glob("*.pdf"))
    r = cli(*args)
    assert r.returncode == 0, r.stderr


@pytest.mark.slow
def test_a_quarantined_file_exits_1_and_the_good_files_are_still_processed(tmp_path):
    good = _inbox(tmp_path / "inbox")[0]
    (tmp_path / "inbox" / "broken.mcap").write_bytes(good.read_bytes()[:5000])
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1", "--no-reports")
    assert r.returncode == 1, r.stderr
    assert "1 ingested" in r.stderr and "quarantined: broken.mcap" in r.stderr
    # the same bad file seen again is unchanged, not a new problem
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1", "--no-reports")
    assert r.returncode == 0, r.stderr
    # `ingest` follows the same table
    r = cli("ingest", tmp_path / "inbox", "--warehouse", tmp_path / "wh2")
    assert r.returncode == 1, r.stderr


@pytest.mark.slow
def test_a_failed_stage_exits_1(tmp_path):
    studies = tmp_path / "studies" / "broken"
    studies.mkdir(parents=True)
    (studies / "study.toml").write_text('[stages.orientation]\nestimator = "no-such-filter"\n')
    _inbox(tmp_path / "inbox", study="broken")
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1", "--no-reports",
            env={"STRIDELAB_STUDIES": str(tmp_path / "studies")})
    assert r.returncode == 1, r.stderr
    assert "failed: orientation broken-S0" in r.stderr


@pytest.mark.slow
def test_a_report_that_cannot_be_written_exits_1(tmp_path):
    _inbox(tmp_path / "inbox")
    (tmp_path / "not-a-dir").write_text("x")
    r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh", "-j", "1",
            "--reports", tmp_path / "not-a-dir" / "reports")   # mkdir fails: a file is in the way
    assert r.returncode == 1, r.stderr
    assert "failed: report testing/P001" in r.stderr


@pytest.mark.slow
def test_lock_held_exits_2(tmp_path):
    (tmp_path / "wh").mkdir()
    with RunLock(tmp_path / "wh", "stridelab run (test holder)"):
        r = cli("run", "--inbox", tmp_path / "inbox", "--warehouse", tmp_path / "wh")
        assert r.returncode == 2
        assert r.stderr.strip().splitlines()[-1].startswith("error: another stridelab process")
        r = cli("ingest", tmp_path, "--warehouse", tmp_path / "wh")
        assert r.returncode == 2


@pytest.mark.parametrize("args", [("run", "--jobs", "0"), ("run", "--scheduler", "tcp://x:1"),
                                  ("run", "--no-such-option"), ("ingest",)])
def test_bad_arguments_exit_2(tmp_path, args):
    r = cli(*args, "--warehouse", tmp_path / "wh") if args[0] == "run" else cli(*args)
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert not (tmp_path / "wh").exists()          # nothing was started
