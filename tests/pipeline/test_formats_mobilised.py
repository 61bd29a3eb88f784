"""pipeline/formats/mobilised.py on hand-made data.mat files and on the real Mobilise-D sample."""
from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io as sio

from stridelab.pipeline.formats.mobilised import find_mobilised_files, read_mobilised
from tests.conftest import shared_data


def _trial(n=500, fs=100, start="2021-03-01T10:00:00.000+01:00", bouts=None):
    rng = np.random.default_rng(1)
    acc = np.tile([1.0, 0.0, 0.0], (n, 1)) + 0.01 * rng.standard_normal((n, 3))   # g, x vertical
    gyr = np.tile([0.0, 0.0, 90.0], (n, 1))                                       # deg/s
    su = {"LowerBack": {"Acc": acc, "Gyr": gyr, "Mag": np.ones((n, 3)), "Timestamp": 1.6e9 + np.arange(n) / fs,
                        "Fs": {"Acc": fs, "Gyr": fs}}}
    if bouts is None:
        bouts = [{"Start": 1.0, "End": 3.5, "Cadence": 110.0, "AverageStrideLength": 1.3, "WalkingSpeed": 1.2,
                  "NumberStrides": 2, "InitialContact_Event": np.array([1.0, 1.55, 2.1, 2.65]),
                  "InitialContact_LeftRight": np.array(["Left", "Right", "Left", "Right"], dtype=object),
                  "Turn_Start": np.zeros(0), "Turn_End": np.zeros(0)},
                 {"Start": 4.0, "End": 4.9, "Cadence": 100.0, "AverageStrideLength": 1.1, "WalkingSpeed": 0.9,
                  "NumberStrides": 1, "InitialContact_Event": np.array([4.0, 4.6]),
                  "InitialContact_LeftRight": np.array(["Right", "Left"], dtype=object),
                  "Turn_Start": np.array([4.1]), "Turn_End": np.array([4.6]), "Turn_Angle": np.array([-90.0])}]
    return {"StartDateTime": start, "TimeZone": "Europe/Rome", "SU": su,
            "Standards": {"INDIP": {"MicroWB": np.array(bouts, dtype=object) if len(bouts) > 1 else bouts[0],
                                    "Fs": fs}}}


def _write(tmp_path, data, info=None, cohort="MS", pid="007"):
    d = tmp_path / cohort / pid
    d.mkdir(parents=True)
    sio.savemat(d / "data.mat", {"data": data})
    if info is not None:
        sio.savemat(d / "infoForAlgo.mat", {"infoForAlgo": info})
    return d / "data.mat"


def test_hand_made_units_times_references(tmp_path):
    f = _write(tmp_path, {"TimeMeasure1": {"Test5": {"Trial1": _trial(), "Trial2": _trial(n=300)}}},
               info={"TimeMeasure1": {"Height": 172, "Weight": 80, "SensorHeight": 95.0, "LegLength": 88.0,
                                      "WalkingAid_01": 1, "Handedness": "L"}})
    trials = read_mobilised(f)
    assert [t.trial for t in trials] == ["Trial1", "Trial2"]
    t = trials[0]
    assert (t.participant_id, t.cohort, t.test, t.fs_hz) == ("MS-007", "MS", "Test5", 100.0)
    np.testing.assert_allclose(np.median(t.acc[:, 0]), 9.81, atol=0.05)       # g → m/s²
    np.testing.assert_allclose(t.gyr[:, 2], np.pi / 2)                          # 90 deg/s → rad/s
    # 10:00 at +01:00 is 09:00 UTC
    assert t.start_utc_ns == int(np.datetime64("2021-03-01T09:00:00", "ns").astype(np.int64))
    assert t.timezone == "Europe/Rome"
    r = t.reference("INDIP")
    np.testing.assert_array_equal(r.start_s, [1.0, 4.0])
    np.testing.assert_array_equal(r.walking_speed_m_s, [1.2, 0.9])
    assert r.ic_side.tolist() == ["left", "right", "left", "right", "right", "left"]
    assert r.ic_bout.tolist() == [0, 0, 0, 0, 1, 1]
    np.testing.assert_array_equal(r.turn_angle_deg, [-90.0])
    assert t.reference("Stereophoto") is None
    assert t.info.height_m == pytest.approx(1.72) and t.info.leg_length_m == pytest.approx(0.88)
    assert t.info.walking_aid is True and t.info.sensor_height_m == pytest.approx(0.95)


def test_single_bout_struct_and_no_info(tmp_path):
    b = _trial()["Standards"]["INDIP"]["MicroWB"][0]
    f = _write(tmp_path, {"TimeMeasure2": {"Test11": {"Trial1": _trial(bouts=[b])}}})
    (t,) = read_mobilised(f.parent)                       # a participant folder works too
    assert t.reference("INDIP").start_s.tolist() == [1.0]
    assert t.info.height_m is None
    assert find_mobilised_files(tmp_path) == [f]


@pytest.mark.parametrize("mutate, message", [
    (lambda tr: tr["SU"]["LowerBack"].pop("Gyr"), "has no Gyr"),
    (lambda tr: tr["SU"]["LowerBack"]["Acc"].__setitem__((slice(5, 9), 1), np.nan), "NaN or Inf"),
    (lambda tr: tr.__setitem__("StartDateTime", "yesterday"), "not ISO 8601"),
    (lambda tr: tr["Standards"]["INDIP"]["MicroWB"][0].__setitem__("End", 0.5), "not a valid interval"),
])
def test_malformed_one_line_naming_file(tmp_path, mutate, message):
    tr = _trial()
    mutate(tr)
    f = _write(tmp_path, {"TimeMeasure1": {"Test5": {"Trial1": tr}}})
    with pytest.raises(ValueError) as e:
        read_mobilised(f)
    assert str(f) in str(e.value) and message in str(e.value) and "\n" not in str(e.value)


def test_not_a_mat_file(tmp_path):
    d = tmp_path / "HA" / "001"
    d.mkdir(parents=True)
    (d / "data.mat").write_text("hello")
    with pytest.raises(ValueError, match="data.mat"):
        read_mobilised(d / "data.mat")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no data.mat"):
        find_mobilised_files(tmp_path / "empty")


def test_v73_hdf5(tmp_path):
    """A MATLAB v7.3 file (HDF5) written by hand the way MATLAB lays it out (column-major, char as uint16)."""
    h5py = pytest.importorskip("h5py")
    d = tmp_path / "HA" / "002"
    d.mkdir(parents=True)
    n = 200
    with h5py.File(d / "data.mat", "w", userblock_size=512) as f:
        tr = f.create_group("data/TimeMeasure1/Test5/Trial1")
        s = np.frombuffer("2021-03-01T10:00:00.000+00:00".encode("utf-16-le"), np.uint16).reshape(-1, 1)
        ds = tr.create_dataset("StartDateTime", data=s)
        ds.attrs["MATLAB_class"] = np.bytes_("char")
        lb = tr.create_group("SU/LowerBack")
        lb.create_dataset("Acc", data=np.tile([[1.0], [0.0], [0.0]], (1, n)))     # stored transposed
        lb.create_dataset("Gyr", data=np.zeros((3, n)))
        lb.create_dataset("Fs/Acc", data=np.array([[100.0]]))
        w = tr.create_group("Standards/INDIP/MicroWB")
        w.create_dataset("Start", data=np.array([[0.5]]))
        w.create_dataset("End", data=np.array([[1.5]]))
    hdr = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Dec  7 12:00:00 2026 HDF5 schema 1.00 ."
    with open(d / "data.mat", "r+b") as fh:               # MATLAB's 128-byte header in the HDF5 user block
        fh.write(hdr.ljust(116) + b"\0" * 8 + b"\x00\x02" + b"IM")
    (t,) = read_mobilised(d / "data.mat")
    assert t.acc.shape == (n, 3) and t.acc[0, 0] == pytest.approx(9.81)
    assert t.start_utc_ns == int(np.datetime64("2021-03-01T10:00:00", "ns").astype(np.int64))
    assert t.reference("INDIP").end_s.tolist() == [1.5]


@pytest.mark.realdata
def test_real_sample():
    root = shared_data("mobilised_lab")
    (f,) = find_mobilised_files(root)
    trials = read_mobilised(f)
    listed = json.loads((f.parent / "test_list.json").read_text())["data"]
    assert sorted(t.name.split("_", 1)[1] for t in trials) == sorted("_".join(e["key"]) for e in listed)
    for t in trials:
        assert t.fs_hz == 100.0 and t.timezone == "Europe/Berlin"
        # standing still at the start: |acc| ≈ 1 g once converted, gyro in rad/s is small
        np.testing.assert_allclose(np.linalg.norm(t.acc[:50], axis=1).mean(), 9.81, rtol=0.05)
        assert np.median(np.abs(t.gyr[:50])) < 0.3          # would be ~57× larger left in deg/s
        for system in ("INDIP", "Stereophoto"):
            r = t.reference(system)
            assert r is not None and r.start_s.size >= 1
            assert np.all(r.end_s > r.start_s) and np.all(r.end_s <= t.acc.shape[0] / t.fs_hz)
            assert set(r.ic_side.tolist()) <= {"left", "right"}
            assert np.all((r.walking_speed_m_s > 0.2) & (r.walking_speed_m_s < 2.5))
    assert trials[0].info.height_m == pytest.approx(1.59)
