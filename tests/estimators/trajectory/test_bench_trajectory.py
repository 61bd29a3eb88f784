"""Loop CSV reader + ``stridelab bench trajectory`` on a simulated loop walk (jitter, repeated timestamps)."""
from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from validation.simulator.foot_walk_yun import simulate_yun_walk
from estimators.quaternion import quat_from_axis_angle, quat_rotate
from pipeline.formats.loop_csv import COLUMNS, load_loop_csv


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


def test_bench_trajectory_cli(tmp_path):
    from validation.bench.trajectory import command
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
        assert r["final_position_error_m"] < 0.3


def test_bench_trajectory_bad_file(tmp_path):
    from validation.bench.trajectory import command
    p = tmp_path / "bad.csv"
    p.write_text("a,b\n1,2\n")
    res = CliRunner().invoke(command, ["--loop", str(p), "--json"])
    assert res.exit_code == 2 and "missing column" in res.output
