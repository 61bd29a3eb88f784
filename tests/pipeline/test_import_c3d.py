"""``stridelab import c3d``: C3D markers (written here with ezc3d) as the optical reference beside a recording: the
recording's messages unchanged, the markers as ``/reference/pose/<placement>`` in metres on the recording's clock,
and the stages using them as they use the gaitmap markers."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from stridelab.estimators.recording import ImuData, Recording
from stridelab.cli import main
from stridelab.pipeline.privacy import name_token as T
from stridelab.pipeline.formats.mcap_write import write_recording
from tests.conftest import shared_data
from tests.pipeline.test_import import read_mcap

T0 = 1_700_000_000_000_000_000


def write_c3d(path, labels, xyz_mm, rate_hz, units="mm"):
    """xyz_mm (N, M, 3) in ``units``, NaN = occluded."""
    import ezc3d
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rate_hz)]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = [units]
    pts = np.ones((4, len(labels), xyz_mm.shape[0]))
    pts[:3] = np.transpose(xyz_mm, (2, 1, 0))
    c["data"]["points"] = pts
    c.write(str(path))


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.stack([np.stack([c, -s, np.zeros_like(a)], -1), np.stack([s, c, np.zeros_like(a)], -1),
                     np.tile([0.0, 0.0, 1.0], (len(a), 1))], -2)


def _recording(path, n=800, fs=200.0):
    rng = np.random.default_rng(4)
    t = T0 + np.rint(np.arange(n) * 1e9 / fs).astype(np.int64)
    imu = ImuData(t, rng.normal(0, 1, (n, 3)) + [0, 0, 9.81], rng.normal(0, 0.5, (n, 3)))
    rec = Recording({"study": "imported", "participant": "P01", "session": "P01-walk", "kind": "lab",
                     "trial": "walk", "timezone": "UTC"}, imu={"foot_left": imu}, name="walk")
    return write_recording(rec, path)


def _cluster(n, rate):
    """Heel, toe, 5th metatarsal of a foot turning about z and moving along x (mm), one toe frame occluded."""
    yaw = np.linspace(0, np.pi / 2, n)
    R = _rot_z(yaw)
    local = np.array([[0.0, 0, 0], [200, 0, 0], [150, -40, 0]])          # heel, toe, 5th metatarsal
    heel = np.column_stack([np.linspace(0, 1500, n), np.full(n, 300.0), np.full(n, 60.0)])
    xyz = heel[:, None, :] + np.einsum("nij,mj->nmi", R, local)
    xyz[7, 1] = np.nan
    return xyz, R


def test_c3d_markers_become_reference_poses_on_the_recording_clock(tmp_path):
    rec = _recording(tmp_path / "walk.mcap")
    n, rate = 300, 100.0
    xyz, R = _cluster(n, rate)
    write_c3d(tmp_path / "walk.c3d", ["LHEE", "LTOE", "LMT5"], xyz, rate)
    r = CliRunner().invoke(main, ["import", "c3d", str(tmp_path / "walk.c3d"), "--recording", str(rec),
                                  "--segment", "foot_left=LHEE,LTOE,LMT5", "--offset-s", "0.5",
                                  "--inbox", str(tmp_path / "inbox"), "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)["written"][0]
    assert Path(out).name == f"rec-{T('walk.mcap')}+c3d-{T('walk.c3d')}.mcap"    # no file name kept
    src, _, sess0 = read_mcap(rec)
    topics, _, sess = read_mcap(out)
    for k in ("/imu/foot_left",):                                   # the recording's messages unchanged
        np.testing.assert_array_equal(topics[k][0], src[k][0])
        np.testing.assert_array_equal(topics[k][1], src[k][1])
    t, v = topics["/reference/pose/foot_left"]
    np.testing.assert_array_equal(t, T0 + 500_000_000 + np.arange(n) * 10_000_000)      # first IMU + offset + i/rate
    np.testing.assert_allclose(v[:, :3], xyz[:, 0] / 1000.0, atol=1e-6)                  # heel, mm -> m
    from stridelab.estimators.quaternion import quat_to_matrix
    ok = np.isfinite(v[:, 3])
    assert ok.sum() == n - 1 and not ok[7]                          # the occluded toe frame: no orientation
    # cluster frame: x = heel->toe, z = x × heel->5th metatarsal (down here: the 5th metatarsal is at -y), y = z × x
    np.testing.assert_allclose(quat_to_matrix(v[ok, 3:]), R[ok] @ np.diag([1.0, -1.0, -1.0]), atol=1e-5)
    assert sess["reference_frame"] == "segment_lab" and "walk" not in sess["reference"] and "mm -> m" in sess["reference"]
    assert {k: sess[k] for k in sess0} == sess0


def test_y_up_capture_volume_is_rotated_to_z_up(tmp_path):
    rec = _recording(tmp_path / "walk.mcap")
    xyz = np.zeros((100, 1, 3))
    xyz[:, 0, 1] = 900.0                                           # 0.9 m up a y-up volume
    write_c3d(tmp_path / "up.c3d", ["HEEL"], xyz, 100.0)
    r = CliRunner().invoke(main, ["import", "c3d", str(tmp_path / "up.c3d"), "--recording", str(rec), "--up", "y",
                                  "--segment", "foot_left=HEEL", "--inbox", str(tmp_path / "inbox"), "--json"])
    assert r.exit_code == 0, r.output
    topics, _, _ = read_mcap(json.loads(r.stdout)["written"][0])
    p = topics["/reference/pose/foot_left"][1]
    np.testing.assert_allclose(p[:, :3], np.tile([0, 0, 0.9], (100, 1)), atol=1e-6)
    assert np.isnan(p[:, 3:]).all()                                 # one marker: position only


@pytest.mark.parametrize("args, needle", [
    ([], "give at least one --segment"),
    (["--segment", "foot_left=LHEE,NOPE,LMT5"], "marker 'NOPE' not in the file; labels: LHEE, LTOE, LMT5"),
    (["--segment", "foot_left=LHEE,LTOE,LMT5", "--offset-s", "60"], "do not overlap the recording"),
    (["--segment", "foot_left=LHEE,LTOE"], "expected PLACEMENT=MARKER or PLACEMENT=M1,M2,M3"),
])
def test_bad_c3d_import_one_line_nothing_written(tmp_path, args, needle):
    rec = _recording(tmp_path / "walk.mcap")
    write_c3d(tmp_path / "walk.c3d", ["LHEE", "LTOE", "LMT5"], _cluster(100, 100.0)[0], 100.0)
    r = CliRunner().invoke(main, ["import", "c3d", str(tmp_path / "walk.c3d"), "--recording", str(rec), *args,
                                  "--inbox", str(tmp_path / "inbox")])
    assert r.exit_code != 0
    lines = [x for x in r.output.splitlines() if x.strip()]
    assert len(lines) == 1 and needle in lines[0], r.output
    assert not (tmp_path / "inbox").exists() or not list((tmp_path / "inbox").iterdir())


def test_damaged_c3d_or_recording_one_line(tmp_path):
    rec = _recording(tmp_path / "walk.mcap")
    (tmp_path / "bad.c3d").write_bytes(b"\x02P" + b"\x00" * 300)
    write_c3d(tmp_path / "ok.c3d", ["LHEE"], np.zeros((50, 1, 3)), 100.0)
    (tmp_path / "cut.mcap").write_bytes(rec.read_bytes()[:500])
    for c3d, recording, needle in (("bad.c3d", rec, "not a readable C3D file"),
                                   ("ok.c3d", tmp_path / "cut.mcap", "cut.mcap")):
        r = CliRunner().invoke(main, ["import", "c3d", str(tmp_path / c3d), "--recording", str(recording),
                                      "--segment", "foot_left=LHEE", "--inbox", str(tmp_path / "inbox")])
        lines = [x for x in r.output.splitlines() if x.strip()]
        assert r.exit_code != 0 and len(lines) == 1 and needle in lines[0], r.output
    assert not (tmp_path / "inbox").exists() or not list((tmp_path / "inbox").iterdir())


@pytest.mark.realdata
@pytest.mark.slow
def test_gait_stage_scores_c3d_markers_as_it_scores_the_gaitmap_markers(tmp_path, monkeypatch):
    """The gaitmap walk twice: as ``import gaitmap`` writes it (markers from mocap_sample.csv), and as its IMUs alone
    plus the same markers written to a C3D in mm and imported with ``import c3d``: the orientation and gait stages'
    accuracy (foot orientation, stride length, trajectory) is the same."""
    from stridelab.pipeline.formats.gaitmap import load_gaitmap_example
    from stridelab.pipeline.importers import import_paths
    from stridelab.pipeline.stages import gait, orientation
    from tests.pipeline._lab import df, run_with
    src = shared_data("gaitmap_example")
    ex = load_gaitmap_example(src)
    direct = import_paths("gaitmap", [src], tmp_path / "a", study="public").written
    topics, events, sess = read_mcap(direct[0])
    imu = {pl: ImuData(topics[f"/imu/{pl}"][0], topics[f"/imu/{pl}"][1][:, 3:], topics[f"/imu/{pl}"][1][:, :3])
           for pl in ("foot_left", "foot_right")}
    bare = write_recording(Recording({**sess, "session": "gaitmap01-walk-c3d"}, imu=imu, events=events,
                                     name="walk"), tmp_path / "walk.mcap")
    labels, cols = [], []
    for foot in (ex.left, ex.right):
        for m in ("FCC", "TOE", "FM5"):
            labels.append(f"{foot.side[0].upper()}_{m}")
            cols.append(foot.markers[m] * 1000.0)
    write_c3d(tmp_path / "walk.c3d", labels, np.stack(cols, axis=1), ex.mocap_rate_hz)
    r = CliRunner().invoke(main, ["import", "c3d", str(tmp_path / "walk.c3d"), "--recording", str(bare),
                                  "--segment", "foot_left=L_FCC,L_TOE,L_FM5", "--segment", "foot_right=R_FCC,R_TOE,R_FM5",
                                  "--inbox", str(tmp_path / "b"), "--json"])
    assert r.exit_code == 0, r.output
    via_c3d = json.loads(r.stdout)["written"]
    got = {}
    for name, files in (("direct", direct), ("c3d", via_c3d)):
        run_with(monkeypatch, tmp_path / f"wh-{name}", files, [orientation.STAGE, gait.STAGE])
        got[name] = df(tmp_path / f"wh-{name}", "SELECT stage, placement, metric, value FROM accuracy_metrics "
                                                "WHERE stage IN ('strides', 'foot_trajectory', 'orientation') "
                                                "ORDER BY ALL")
    assert len(got["direct"]) >= 4 and got["direct"][["stage", "placement", "metric"]].equals(
        got["c3d"][["stage", "placement", "metric"]])
    np.testing.assert_allclose(got["c3d"]["value"], got["direct"]["value"], rtol=1e-4)
    # the foot orientation vs the FCC/TOE/FM5 cluster after mounting + lab heading alignment: a few degrees (38°
    # before the alignment's multi-start: lab x is ≈150° from the IMUs' heading)
    ori = got["c3d"][(got["c3d"]["stage"] == "orientation") & (got["c3d"]["metric"] == "total_rmse_deg")]
    assert len(ori) == 2 and (ori["value"] < 8.0).all(), ori


def test_reference_text_of_many_segments_fits_the_screened_label():
    """Seven segments' marker lists would pass the 120 characters of a screened label (the recording would be
    refused at ingest): the text then gives the marker count and the placements, or their number."""
    from stridelab.pipeline.c3d_reference import Segment, reference_text
    from stridelab.pipeline.privacy import screen_session
    from stridelab.studies.privacy import PrivacyPolicy
    one = reference_text([Segment("foot_left", ("LHEE", "LTOE", "LMT5"))], "mm", 100.0, 0.5)
    assert one == "C3D markers (foot_left = LHEE/LTOE/LMT5; mm -> m, 100 Hz, offset 0.5 s)"
    pls = ("pelvis", "thigh_left", "thigh_right", "shank_left", "shank_right", "foot_left", "foot_right")
    many = reference_text([Segment(p, tuple(f"M{j}{i}" for i in range(3))) for j, p in enumerate(pls)],
                          "mm", 100.0, 0.25)
    assert len(many) <= 120 and "21 on 7 segments" in many
    four = reference_text([Segment(p, ("A", "B", "C")) for p in pls[3:]], "mm", 100.0, 0.25)
    assert len(four) <= 120 and "12 on shank_left, shank_right, foot_left, foot_right;" in four
    base = {"study": "testing", "participant": "P001", "session": "S01", "kind": "lab", "trial": "walk-1"}
    assert screen_session({**base, "reference": many}, PrivacyPolicy())["reference"] == many
