"""Loop CSV reader + ``stridelab bench trajectory`` on a simulated loop walk (jitter, repeated timestamps)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from stridelab.validation.simulator.foot_walk_yun import simulate_yun_walk
from stridelab.estimators.quaternion import quat_from_axis_angle, quat_rotate
from stridelab.pipeline.formats.loop_csv import COLUMNS, load_loop_csv


def _write_loop_csv(path, seed=0):
    sim = simulate_yun_walk(36, noise_scale=1.0, seed=seed, sampling_rate_hz=200, stride_m=1.0, height_m=0.12,
                            heading_rate_deg_per_stride=10.0)          # 36 strides x 10 deg = closed polygon
    mount = quat_from_axis_angle(np.array([1.0, 2.0, 0.5]), np.array([2.0]))    # unknown mounting
    gyr = quat_rotate(mount, sim.gyr)
    acc = quat_rotate(mount, sim.acc)
    rng = np.random.default_rng(seed)
    t = np.arange(len(gyr)) / 200.0 + rng.uniform(-1e-4, 1e-4, len(gyr))
    rows = np.column_stack([t, np.degrees(gyr), acc / 9.80665])
    rows = np.insert(rows, 500, rows[499], axis=0)                      # a repeated timestamp
    with open(path, "w") as f:
        f.write(",".join(COLUMNS) + "\n")
        np.savetxt(f, rows, delimiter=",", fmt="%.7f")
    return sim


def test_loop_reader(tmp_path):
    p = tmp_path / "loop.csv"
    _write_loop_csv(p)
    rec = load_loop_csv(p)
    assert rec.sampling_rate_hz == 200.0 and rec.n_duplicates == 1
    assert abs(np.median(np.linalg.norm(rec.acc, axis=1)) - 9.81) < 0.05


@pytest.mark.slow
def test_bench_trajectory_cli(tmp_path):
    from stridelab.validation.bench.trajectory import command
    paths = []
    for seed in (0, 1):
        p = tmp_path / f"loop{seed}.csv"
        _write_loop_csv(p, seed)
        paths.append(p)
    res = CliRunner().invoke(command, ["--loop", str(paths[1]), "--loop", str(paths[0]), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert [r["file"] for r in out["files"]] == [str(paths[1]), str(paths[0])]
    for r in out["files"]:
        assert abs(r["distance_m"] - 36.0) < 0.5
        # horizontal: this simulator (stridelab.validation.simulator.foot_walk_yun) holds each angular rate constant over the
        # sample interval that follows it (θ piecewise linear, rate steps at the sample instants), for which the
        # forward-Euler attitude is exact; the shipped midpoint rule with PyShoe's 2.5 ms gyro delay (issue 43,
        # chosen on real recordings, where rates are continuous) lifts its foot ~17 mm per stride. The height
        # rule is tested on continuously sampled motion in test_issue43_failure_modes.py.
        assert r["final_position_error_xy_m"] < 0.3


def test_bench_trajectory_bad_file(tmp_path):
    from stridelab.validation.bench.trajectory import command
    p = tmp_path / "bad.csv"
    p.write_text("a,b\n1,2\n")
    res = CliRunner().invoke(command, ["--loop", str(p), "--json"])
    assert res.exit_code == 2 and "missing column" in res.output


@pytest.mark.slow
def test_bench_loop_lists_an_unreadable_file_and_goes_on(tmp_path):
    """Issue 43 point 3: one bad file among good ones is listed with its reason; the others are scored, exit 0;
    the loop blocks carry the horizontal and 3-D final errors."""
    from stridelab.validation.bench.trajectory import command
    good = tmp_path / "loop0.csv"
    _write_loop_csv(good, 0)
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    res = CliRunner().invoke(command, ["--loop", str(bad), "--loop", str(good), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)["loop"]
    assert [r["file"] for r in out["files"]] == [str(good)]
    assert out["unreadable"][0]["file"] == str(bad) and "missing column" in out["unreadable"][0]["reason"]
    sd = out["shipped_defaults"]
    # 3-D not bounded here: the simulator's held rates (see test_bench_trajectory_cli) lift its foot under the
    # shipped midpoint rule; the horizontal error is the one the simulator can judge
    assert sd["final_position_error_xy_m"][0] <= sd["final_position_error_3d_m"][0]
    assert sd["final_position_error_xy_m"][0] < 0.3
    assert out["cross_validated"] == "needs >= 2 readable walks"


@pytest.mark.realdata
def test_bench_pyshoe_lists_an_unreadable_file_and_goes_on(tmp_path):
    from tests.conftest import shared_data
    from stridelab.validation.bench.trajectory import pyshoe_benchmark
    src = sorted(shared_data("pyshoe_vicon").glob("*.mat"))[0]
    (tmp_path / src.name).symlink_to(src)
    (tmp_path / "broken.mat").write_bytes(b"not a mat file")
    out = pyshoe_benchmark(tmp_path, show_progress=False, anchors=False)
    assert [b["file"] for b in out["unreadable"]] == [str(tmp_path / "broken.mat")]
    assert "broken.mat" in out["unreadable"][0]["reason"]
    for block in ("shipped_defaults", "cross_validated", "in_sample"):
        s = out[block]
        assert s["n_trials"] == 1 and s["mean_m"] <= s["mean_3d_m"] + 1e-9 or s["mean_3d_m"] is None
        assert set(s["by_activity"]) == {out["trials"][0]["motion_type"]}
