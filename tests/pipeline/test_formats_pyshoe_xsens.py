"""The PyShoe .mat and Xsens MT / Voisard readers (stridelab.pipeline.formats.pyshoe, .xsens_mt) on files written here from
the documented layouts, bad files refused with one line naming the file, and the public files when present."""
from __future__ import annotations

import json

import numpy as np
import pytest

from stridelab.pipeline.formats.pyshoe import load_pyshoe_dir, load_pyshoe_trial
from stridelab.pipeline.formats.xsens_mt import load_voisard_dir, load_voisard_json, load_xsens_mt_txt
from tests.conftest import shared_data


def _write_mat(path, n=400, fs=200.0, **override):
    import scipy.io as sio
    rng = np.random.default_rng(1)
    imu = np.column_stack([rng.normal(0, 0.1, (n, 2)), np.full(n, 9.81), rng.normal(0, 0.01, (n, 3))])
    d = {"imu": imu, "ts": (np.arange(n) / fs + 5.0)[None, :], "gt": np.column_stack(
        [np.linspace(0, 1, n), np.linspace(0, 2, n), np.full(n, 0.1)]), "zv_shoe_opt": (np.arange(n) % 2)[None, :]}
    d.update(override)
    sio.savemat(path, d)
    return imu


def test_pyshoe_layout_units_and_y_flip(tmp_path):
    imu = _write_mat(tmp_path / "a.mat")
    tr = load_pyshoe_trial(tmp_path / "a.mat")
    np.testing.assert_array_equal(tr.acc, imu[:, :3])
    np.testing.assert_array_equal(tr.gyr, imu[:, 3:])
    assert tr.sampling_rate_hz == pytest.approx(200.0)
    assert tr.position[-1, 1] == pytest.approx(-2.0) and tr.position[-1, 0] == pytest.approx(1.0)   # y flipped
    assert tr.oracle_zv["shoe"].dtype == bool and tr.oracle_zv["shoe"].sum() == 200


def test_pyshoe_bad_files_name_the_file(tmp_path):
    _write_mat(tmp_path / "short_gt.mat", gt=np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"short_gt\.mat.*one timestamp"):
        load_pyshoe_trial(tmp_path / "short_gt.mat")
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all" * 10)
    with pytest.raises(ValueError, match=r"junk\.mat"):
        load_pyshoe_trial(tmp_path / "junk.mat")
    with pytest.raises(ValueError, match="no .mat files"):
        load_pyshoe_dir(tmp_path / "nothing_here")


def _write_xsens(path, n=50, fs=100, drop=(), header=None):
    cols = header or ["PacketCounter", "SampleTimeFine", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z",
                      "Mag_X", "Mag_Y", "Mag_Z"]
    lines = [f"Acquisition frequency: {fs} Hz", "\t".join(cols)]
    for k in range(n):
        if k in drop:
            continue
        vals = [float(k), 1000.0 * k, 0.1, 0.2, 9.8, 0.01 * k, -0.02, 0.03, 0.5, 0.0, -0.8]
        lines.append("\t".join(str(v) for v in vals[:len(cols)]))
    path.write_text("\n".join(lines) + "\n")


def test_xsens_columns_by_name_rate_and_dropped_packets(tmp_path):
    _write_xsens(tmp_path / "x.txt", drop=(10, 11, 30))
    r = load_xsens_mt_txt(tmp_path / "x.txt")
    assert r.sampling_rate_hz == 100.0 and r.acc.shape == (47, 3) and r.n_dropped == 3
    np.testing.assert_allclose(r.acc[0], [0.1, 0.2, 9.8])
    np.testing.assert_allclose(r.gyr[12, 0], 0.14)          # row 12 is packet 14 after two drops
    np.testing.assert_allclose(r.mag[0], [0.5, 0.0, -0.8])


def test_on_packet_grid_fills_dropped_packets_and_unwraps(tmp_path):
    from stridelab.pipeline.formats.xsens_mt import on_packet_grid
    _write_xsens(tmp_path / "x.txt", drop=(10, 11, 30))
    g = on_packet_grid(load_xsens_mt_txt(tmp_path / "x.txt"))
    assert g.acc.shape == (50, 3) and g.filled.sum() == 3 and list(np.flatnonzero(g.filled)) == [10, 11, 30]
    np.testing.assert_allclose(g.gyr[:, 0], 0.01 * np.arange(50))          # linear signal rebuilt exactly
    np.testing.assert_array_equal(g.packet, np.arange(50))
    r = load_xsens_mt_txt(tmp_path / "x.txt")
    from dataclasses import replace
    wrapped = replace(r, packet=(r.packet + 65530) % 65536)                 # the 16-bit counter wraps at 6
    assert on_packet_grid(wrapped).acc.shape == (50, 3)


def test_xsens_bad_files_name_the_file(tmp_path):
    p = tmp_path / "norate.txt"
    _write_xsens(p)
    p.write_text("\n".join(p.read_text().splitlines()[1:]))
    with pytest.raises(ValueError, match=r"norate\.txt.*Acquisition frequency"):
        load_xsens_mt_txt(p)
    q = tmp_path / "nogyr.txt"
    _write_xsens(q, header=["PacketCounter", "Acc_X", "Acc_Y", "Acc_Z"])
    with pytest.raises(ValueError, match=r"nogyr\.txt.*Gyr_X"):
        load_xsens_mt_txt(q)


def _write_json(path, **override):
    d = {"Subject": 3, "Trial": 2, "Filename": "3-2", "Age": 30, "Gender": "M", "Height": 180.0, "Weight": 70.0,
         "TrialBoundaries": [100, 900], "UTurnBoundaries": [450, 560],
         "LeftFootEvents": [[120, 170], [230, 280]], "RightFootEvents": [[175, 225]]}
    d.update(override)
    path.write_text(json.dumps(d))


def test_voisard_json_and_folder(tmp_path):
    _write_json(tmp_path / "3-2.json")
    for s in ("lf", "rf"):
        _write_xsens(tmp_path / f"3-2_{s}.txt")
    a = load_voisard_json(tmp_path / "3-2.json")
    assert (a.subject, a.trial, a.height_cm) == (3, 2, 180.0)
    np.testing.assert_array_equal(a.left_events, [[120, 170], [230, 280]])
    np.testing.assert_array_equal(a.trial_boundaries, [100, 900])
    trials = load_voisard_dir(tmp_path)
    assert [t.name for t in trials] == ["3-2"] and trials[0].lower_back is None
    _write_json(tmp_path / "bad.json", LeftFootEvents=[[170, 120]])
    with pytest.raises(ValueError, match=r"bad\.json.*heel-strike >= toe-off"):
        load_voisard_json(tmp_path / "bad.json")
    _write_json(tmp_path / "nokey.json", TrialBoundaries=None)
    (tmp_path / "nokey.json").write_text(json.dumps({"Subject": 1}))
    with pytest.raises(ValueError, match=r"nokey\.json.*TrialBoundaries"):
        load_voisard_json(tmp_path / "nokey.json")


@pytest.mark.realdata
@pytest.mark.slow
def test_public_pyshoe_trials():
    trials = load_pyshoe_dir(shared_data("pyshoe_vicon"))
    assert len(trials) >= 20
    for tr in trials:
        assert tr.sampling_rate_hz == pytest.approx(200.0, abs=0.5)
        g = np.median(np.linalg.norm(tr.acc[:100], axis=1))         # standing still at the start
        assert g == pytest.approx(9.81, abs=0.3)


@pytest.mark.realdata
def test_public_voisard_trial():
    d = shared_data("voisard_gait")
    from stridelab.pipeline.formats.xsens_mt import load_voisard_trial
    raw = load_voisard_trial(d, "1-1", packet_grid=False)
    assert raw.left.acc.shape[0] == raw.right.acc.shape[0] and raw.left.n_dropped > 0      # rows as exported
    tr = load_voisard_trial(d, "1-1")
    assert tr.left.sampling_rate_hz == 100.0
    assert tr.left.acc.shape[0] == raw.left.acc.shape[0] + raw.left.n_dropped              # on the packet grid
    a = tr.annotation
    assert a.subject == 1 and a.left_events.shape[1] == 2
    assert 0 <= a.trial_boundaries[0] < a.trial_boundaries[1] <= tr.left.acc.shape[0]
    assert 9.5 < np.median(np.linalg.norm(tr.left.acc[:100], axis=1)) < 10.8     # this left MTw reads ~10.3 at rest
