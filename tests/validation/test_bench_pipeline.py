"""``stridelab bench pipeline`` end to end on a tiny study: the JSON keys issue 19 asks for, both engines giving
the same warehouse, and ``--inbox`` reusing (and guarding) a simulated study."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

BENCH = [sys.executable, "-m", "stridelab", "bench", "pipeline"]


def _bench(*args, check=True):
    r = subprocess.run([*BENCH, *map(str, args)], capture_output=True, text=True, timeout=900)
    if check:
        assert r.returncode == 0, r.stderr[-2000:]
    return r


@pytest.mark.slow
def test_bench_pipeline_json_engines_and_inbox_reuse(tmp_path):
    inbox = tmp_path / "study"
    common = ("-n", 1, "--hours", 0.05, "--jobs", 2, "--scaling-participants", 0, "--inbox", inbox, "--json")
    first = json.loads(_bench(*common, "--compare-engines").stdout)
    for k in ("run_wall_s", "cpu_s_per_participant_day", "peak_rss_mb", "coordinator_cpu_s", "workers_cpu_s"):
        assert first[k] > 0, k
    assert 0 < first["reading_floor_cpu_s_per_participant_day"] < first["cpu_s_per_participant_day"]
    assert first["cpu_s"] == pytest.approx(first["coordinator_cpu_s"] + first["workers_cpu_s"], rel=0.05)
    assert all(v["cpu_s"] > 0 for v in first["stages"].values() if v["runs"])
    assert 0 < first["stage_cpu_s_per_participant_day"] < first["cpu_s_per_participant_day"]
    assert first["outside_stages_cpu_s_per_participant_day"] == pytest.approx(
        first["cpu_s_per_participant_day"] - first["stage_cpu_s_per_participant_day"])
    assert first["failed"] == [] and first["simulate_s"] > 0
    eng = first["engines"]
    assert eng["identical_warehouse"] is True and eng["dask"]["failed"] == []
    assert eng["dask_over_local_wall"] == pytest.approx(eng["dask"]["run_wall_s"] / eng["local"]["run_wall_s"])

    again = json.loads(_bench(*common).stdout)        # the same study, not simulated again
    assert again["simulate_s"] is None and again["imu_samples"] == first["imu_samples"]

    other = _bench("-n", 2, "--hours", 0.05, "--scaling-participants", 0, "--inbox", inbox, "--json", check=False)
    assert other.returncode != 0
    assert "holds 1 participants" in other.stderr and "use another --inbox folder" in other.stderr


def test_drop_caches_without_permission_is_a_one_line_error(monkeypatch):
    import builtins
    import click
    from stridelab.validation.bench import pipeline as bench

    real_open = builtins.open

    def refuse(path, *a, **k):
        if str(path) == "/proc/sys/vm/drop_caches":
            raise PermissionError(13, "Permission denied")
        return real_open(path, *a, **k)

    monkeypatch.setattr(builtins, "open", refuse)
    with pytest.raises(click.ClickException, match=r"--drop-caches: cannot write /proc/sys/vm/drop_caches "
                                                   r"\(Permission denied\); it needs root"):
        bench._drop_page_cache()


def test_workdir_that_cannot_be_created_is_a_one_line_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = _bench("-n", 1, "--workdir", blocker / "sub", check=False)
    assert r.returncode != 0
    assert r.stderr.strip().splitlines()[-1].startswith(f"Error: --workdir {blocker / 'sub'}: cannot create it")


def test_no_lower_back_simulates_the_chest_only_study_and_guards_its_inbox(tmp_path):
    """``--no-lower-back``: the demo manifest with both of its lower-back IMUs switched off (and nothing else
    changed); an inbox simulated with the other choice is refused rather than benchmarked as this one."""
    import dataclasses
    import click
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.bench import pipeline as bench
    demo, chest = load_manifest(DEFAULT_MANIFEST), load_manifest(bench._chest_only_manifest(tmp_path))
    assert demo.lab.lower_back and demo.free_living.lower_back
    assert not chest.lab.lower_back and not chest.free_living.lower_back
    back_on = dataclasses.replace(chest, lab=dataclasses.replace(chest.lab, lower_back=True),
                                  free_living=dataclasses.replace(chest.free_living, lower_back=True))
    assert back_on == demo
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    (inbox / "P001_free1_day-1.mcap").write_bytes(b"")
    (inbox / bench._STUDY_FILE).write_text(json.dumps({"participants": 1, "hours": 0.05, "lower_back": True,
                                                       "files": ["P001_free1_day-1.mcap"]}))
    assert bench._reuse(inbox, 1, 0.05, lower_back=True) == [inbox / "P001_free1_day-1.mcap"]
    with pytest.raises(click.ClickException, match="with the lower-back sensor, not without it"):
        bench._reuse(inbox, 1, 0.05, lower_back=False)
