"""``stridelab import``: one test per format on a small file written here from the format's documented layout
(values and units checked against what was written), the public file when ../shared/data has it, and bad files
(one line each, nothing written)."""
from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from stridelab.cli import main
from stridelab.pipeline.privacy import name_token as T
from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks, read_metadata
from stridelab.pipeline.importers import import_paths
from tests.conftest import shared_data

G0 = 9.80665


def read_mcap(path):
    """{topic: (t_ns, values)}, events, session record of an MCAP file, through the project's own reader."""
    res = ReadResult()
    topics, events = {}, []
    for b in iter_blocks(path, res):
        if b.kind == "events":
            events += list(b.values)
            continue
        t, v = topics.get(b.topic, (np.zeros(0, np.int64), None))
        topics[b.topic] = (np.concatenate([t, b.t_ns]), b.values if v is None else np.vstack([v, b.values]))
    meta = read_metadata(path) or res.metadata
    return topics, events, meta["session"]


def _imu(topics, pl):
    t, v = topics[f"/imu/{pl}"]
    return t, v[:, :3], v[:, 3:6]        # t, gyr rad/s, acc m/s²


def _no_leftovers(d):
    assert not [p.name for p in d.iterdir() if p.name.startswith(".")], "temporary files left behind"


# ---- x-io / NGIMU CSV -----------------------------------------------------------------------

def _write_xio(path, n=2000, fs=400.0, mag=True):
    rng = np.random.default_rng(1)
    t = np.arange(n) / fs
    gyr_dps = rng.normal(0, 30, (n, 3))
    acc_g = rng.normal(0, 0.1, (n, 3)) + [0, 0, 1]
    cols = ["Time (s)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
            "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)"]
    data = [t, gyr_dps, acc_g]
    mag_ut = rng.normal(0, 5, (n, 3)) + [20, 0, -40]
    if mag:
        cols += ["Magnetometer X (uT)", "Magnetometer Y (uT)", "Magnetometer Z (uT)"]
        data.append(mag_ut)
    np.savetxt(path, np.column_stack(data), delimiter=",", header=",".join(cols), comments="", fmt="%.6f")
    return np.round(gyr_dps, 6), np.round(acc_g, 6), np.round(mag_ut, 6)


def test_xio_csv_units_placement_and_session(tmp_path):
    gyr, acc, mag = _write_xio(tmp_path / "walk.csv")
    (tmp_path / "walk.csv.session.toml").write_text('[session]\nparticipant = "P07"\ntrial = "loop1"\n')
    inbox = tmp_path / "inbox"
    r = CliRunner().invoke(main, ["import", "xio", str(tmp_path / "walk.csv"), "--inbox", str(inbox),
                                  "--placement", "foot_left", "--session", "study=s1",
                                  "--session", "start=2024-05-01T09:00:00Z", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)["written"]
    topics, events, sess = read_mcap(out[0])
    assert sess["study"] == "s1" and sess["participant"] == "P07" and sess["trial"] == "loop1"
    assert sess["kind"] == "lab" and "start" not in sess
    t, g, a = _imu(topics, "foot_left")
    np.testing.assert_allclose(g, np.deg2rad(gyr), atol=1e-12)        # deg/s -> rad/s
    np.testing.assert_allclose(a, acc * G0, atol=1e-12)                # g -> m/s²
    np.testing.assert_allclose(topics["/mag/foot_left"][1] * 1e6, mag, atol=1e-9)   # µT (tesla on the wire)
    assert t[0] == 1714554000 * 10**9 and np.all(np.diff(t) == 2_500_000)
    _no_leftovers(inbox)


def test_xio_without_magnetometer_has_no_mag_topic(tmp_path):
    _write_xio(tmp_path / "a.csv", mag=False)
    res = import_paths("xio", [tmp_path / "a.csv"], tmp_path / "inbox")
    topics, _, _ = read_mcap(res.written[0])
    assert "/imu/foot_right" in topics and not any(k.startswith("/mag/") for k in topics)


# ---- gaitmap / NilsPod ----------------------------------------------------------------------

def _write_gaitmap(d, n=2048):
    """The three files of the gaitmap example layout (data README): two header rows, acc m/s², gyr deg/s,
    markers mm at 100 Hz, stride events in IMU samples."""
    import pandas as pd
    rng = np.random.default_rng(2)
    d.mkdir()
    cols = pd.MultiIndex.from_product([["left_sensor", "right_sensor"],
                                       ["acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z"]], names=["sensor", "axis"])
    imu = pd.DataFrame(rng.normal(0, 1, (n, 12)) + np.tile([0, 0, 9.81, 0, 0, 0], 2), columns=cols)
    imu.to_csv(d / "imu_sample.csv")
    m = n * 100 // 2048
    mcols = pd.MultiIndex.from_product([["L_TOE", "L_FCC", "L_FM5", "R_TOE", "R_FCC", "R_FM5"], ["x", "y", "z"]])
    base = np.array([[200, 0, 50], [0, 0, 50], [150, -40, 30]] * 2, float).ravel()
    mocap = pd.DataFrame(base + np.linspace(0, 1000, m)[:, None] * np.tile([1, 0, 0], 6), columns=mcols)
    mocap.to_csv(d / "mocap_sample.csv")
    ev = pd.DataFrame({"s_id": [0, 1, 0], "foot": ["left", "left", "right"], "start": [100, 400, 150],
                       "end": [400, 700, 450], "ic": [300, 600, 350], "tc": [200, 500, 250],
                       "min_vel": [100, 400, 150], "pre_ic": [50, 300, 100]})
    ev.to_csv(d / "stride_events_sample.csv", index=False)
    return imu


def test_gaitmap_folder_feet_markers_and_events(tmp_path):
    imu = _write_gaitmap(tmp_path / "gm")
    res = import_paths("gaitmap", [tmp_path / "gm"], tmp_path / "inbox", study="public")
    assert not res.errors
    topics, events, sess = read_mcap(res.written[0])
    t, g, a = _imu(topics, "foot_left")
    np.testing.assert_allclose(g, np.deg2rad(imu["left_sensor"][["gyr_x", "gyr_y", "gyr_z"]].to_numpy()), atol=1e-12)
    np.testing.assert_allclose(a, imu["left_sensor"][["acc_x", "acc_y", "acc_z"]].to_numpy(), atol=1e-12)
    assert np.median(np.diff(t)) == pytest.approx(1e9 / 204.8, abs=1)
    tp, pose = topics["/reference/pose/foot_right"]
    assert pose[0, :3] == pytest.approx([0.0, 0.0, 0.05])              # heel marker, mm -> m
    assert np.median(np.diff(tp)) == pytest.approx(1e7, abs=1)          # 100 Hz
    assert np.allclose(np.linalg.norm(pose[:, 3:], axis=1), 1.0)         # foot orientation from 3 markers
    ic = sorted(e["t_ns"] for e in events if e["type"] == "IC" and e["side"] == "left")
    assert ic == [int(t[300]), int(t[600])]
    assert sess["kind"] == "lab" and sess["study"] == "public"


@pytest.mark.realdata
def test_gaitmap_public_example(tmp_path):
    d = shared_data("gaitmap_example")
    from stridelab.pipeline.formats.gaitmap import load_gaitmap_example
    ex = load_gaitmap_example(d)
    res = import_paths("gaitmap", [d], tmp_path / "inbox")
    topics, events, _ = read_mcap(res.written[0])
    _, g, a = _imu(topics, "foot_right")
    np.testing.assert_array_equal(g, ex.right.gyr)
    np.testing.assert_array_equal(a, ex.right.acc)
    assert sum(e["type"] == "IC" for e in events) == len(ex.left.strides) + len(ex.right.strides)


# ---- UCI chest ------------------------------------------------------------------------------

def test_uci_chest_counts_become_m_s2_and_labels_events(tmp_path):
    n, fs = int(120 * 52), 52.0
    rng = np.random.default_rng(3)
    counts = np.round(2048 + 400 * np.tile([0.0, 1.0, 0.0], (n, 1)) + rng.normal(0, 2, (n, 3)))
    labels = np.where(np.arange(n) < n // 2, 3, 4)
    np.savetxt(tmp_path / "5.csv", np.column_stack([np.arange(n), counts, labels]), delimiter=",", fmt="%d")
    res = import_paths("uci", [tmp_path], tmp_path / "inbox")
    topics, events, sess = read_mcap(res.written[0])
    t, g, a = _imu(topics, "chest")
    assert np.median(np.linalg.norm(a, axis=1)) == pytest.approx(G0, rel=0.01)
    assert not g.any()                                      # no gyroscope: zeros flagged as missing (REP-145)
    assert sess["kind"] == "free_living" and sess["accelerometer_only"] == "chest" and sess["participant"] == "uci05"
    assert [(e["label"], e["code"]) for e in events] == [("standing", 3), ("walking", 4)]
    assert events[1]["t_ns"] == int(t[n // 2])
    assert 52 * 0.999 < 1e9 / np.median(np.diff(t)) < 52 * 1.001


# ---- BROAD ----------------------------------------------------------------------------------

def test_broad_optical_reference_and_movement_spans(tmp_path):
    n, fs = 600, 285.7
    rng = np.random.default_rng(4)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[10:20] = np.nan
    mov = np.zeros(n, bool)
    mov[100:300] = True
    with h5py.File(tmp_path / "t1.hdf5", "w") as h:
        for k, v in (("imu_gyr", rng.normal(size=(n, 3))), ("imu_acc", rng.normal(size=(n, 3)) + [0, 0, 9.8]),
                     ("imu_mag", rng.normal(size=(n, 3)) * 10), ("opt_quat", q), ("opt_pos", rng.normal(size=(n, 3))),
                     ("movement", mov)):
            h[k] = v
        h.attrs["sampling_rate"] = fs
        gyr = h["imu_gyr"][()]
    res = import_paths("broad", [tmp_path / "t1.hdf5"], tmp_path / "inbox", placement="hand")
    topics, events, sess = read_mcap(res.written[0])
    t, g, _ = _imu(topics, "hand")
    np.testing.assert_array_equal(g, gyr)
    ref = topics["/reference/pose/hand"][1]
    np.testing.assert_array_equal(ref[:, 3:], q)
    assert sess["reference_frame"] == "sensor_enu"
    (sp,) = [e for e in events if e["type"] == "score"]
    assert (sp["t_ns"], sp["end_ns"]) == (int(t[100]), int(t[299]))


# ---- APDM Opal HDF5 v5 ----------------------------------------------------------------------

def write_apdm(path, labels=("Right Foot", "Lumbar"), n=1280, fs=128.0, t0_us=1_700_000_000_000_000):
    """An APDM v5 file from the documented layout (Sensors/<id>/{Accelerometer, Gyroscope, Magnetometer, Time},
    Sensors/<id>/Configuration attrs 'Label 0', 'Sample Rate')."""
    rng = np.random.default_rng(5)
    out = {}
    with h5py.File(path, "w") as h:
        h.attrs["FileFormatVersion"] = np.int32(5)
        for k, lab in enumerate(labels):
            g = h.create_group(f"Sensors/{1000 + k}")
            d = {"Accelerometer": rng.normal(size=(n, 3)).astype(np.float32) + np.float32(9.8),
                 "Gyroscope": rng.normal(size=(n, 3)).astype(np.float32),
                 "Magnetometer": rng.normal(size=(n, 3)).astype(np.float32) * 20,
                 "Time": (t0_us + np.round(np.arange(n) * 1e6 / fs)).astype(np.uint64)}
            for name, v in d.items():
                g[name] = v
            c = g.create_group("Configuration")
            c.attrs["Label 0"] = np.bytes_(lab)
            c.attrs["Sample Rate"] = np.uint16(fs)
            out[lab] = d
    return out


def test_apdm_v5_sensors_by_label_with_their_clock(tmp_path):
    d = write_apdm(tmp_path / "opals.h5")
    res = import_paths("apdm", [tmp_path / "opals.h5"], tmp_path / "inbox")
    assert not res.errors, res.errors
    topics, _, sess = read_mcap(res.written[0])
    t, g, a = _imu(topics, "foot_right")
    np.testing.assert_array_equal(g, d["Right Foot"]["Gyroscope"].astype(np.float64))
    np.testing.assert_array_equal(a, d["Right Foot"]["Accelerometer"].astype(np.float64))
    np.testing.assert_allclose(topics["/mag/pelvis"][1] * 1e6, d["Lumbar"]["Magnetometer"], rtol=1e-6)
    assert t[0] == 1_700_000_000_000_000_000                        # µs since epoch -> ns
    assert np.array_equal(t, d["Right Foot"]["Time"].astype(np.int64) * 1000)


def test_apdm_older_layout_is_refused_with_one_line(tmp_path):
    with h5py.File(tmp_path / "old.h5", "w") as h:
        h.attrs["FileFormatVersion"] = np.int32(3)
        h["1000/Calibrated/Accelerometers"] = np.zeros((10, 3))
    res = import_paths("apdm", [tmp_path / "old.h5"], tmp_path / "inbox")
    assert not res.written and len(res.errors) == 1
    assert "old.h5" in res.errors[0] and "v5" in res.errors[0] and "\n" not in res.errors[0]


# ---- Axivity CWA ----------------------------------------------------------------------------
# written from the block layout of Open Movement's cwa.h (openmovement Docs/ax3/cwa.h): a 1024-byte "MD" header,
# then 512-byte "AX" data blocks, little-endian, with 16-bit unpacked samples (numAxesBPS 0x32 = 3 axes, 0x62 =
# gyro then accel), the accel scale 1/2^(8+n) g and gyro range 8000/2^n deg/s, and a checksum that makes the
# block's 16-bit word-wise sum zero

def _om_time(y, mo, d, h, mi, s):
    """cwa_timestamp_t: (MSB) YYYYYYMM MMDDDDDh hhhhmmmm mmssssss (LSB), years after 2000."""
    return ((y - 2000) << 26) | (mo << 22) | (d << 17) | (h << 12) | (mi << 6) | s


def write_cwa(path, acc_counts, gyr_counts=None, *, fs=100, device_id=4321, session_id=7, start=(2024, 5, 1, 9, 0, 0)):
    """acc_counts (N, 3) int16 at +-8 g (1/4096 g per count); gyr_counts (N, 3) int16 at 2000 deg/s range
    (2000/32768 deg/s per count), or None for an AX3. Every block carries the whole-second RTC time of one of its
    samples (``timestampOffset``), as the device writes them."""
    import struct
    ax6 = gyr_counts is not None
    rate = (1 << 6) | {100: 10, 50: 9, 200: 11}[fs]          # (16 >> 1) = 8 g range, 3200 / 2^(15 - n) Hz
    gyro_n, accel_n = 2, 4                                   # 8000 / 2^2 = 2000 deg/s; 1 / 2^(8 + 4) g
    h = bytearray(b"\xff" * 1024)
    struct.pack_into("<2sHBHIHII", h, 0, b"MD", 1020, 0x64 if ax6 else 0x00, device_id, session_id, 0, 0, 0xFFFFFFFF)
    struct.pack_into("<IBB", h, 21, 0, 0, 0)
    h[27:35] = bytes(8)
    h[35], h[36] = (gyro_n if ax6 else 0), rate
    struct.pack_into("<IBh", h, 37, _om_time(*start), 45, -1)
    h[44:64] = bytes(20)
    per = 40 if ax6 else 80                                  # samples in the 480 data bytes
    y, mo, d, hh, mi, ss = start
    blocks = [bytes(h)]
    for seq, a in enumerate(range(0, len(acc_counts) - len(acc_counts) % per, per)):
        i = (-a) % fs                                        # a sample of this block on a whole second
        i = i - fs if i >= per else i
        tot = hh * 3600 + mi * 60 + ss + (a + i) // fs
        b = bytearray(512)
        struct.pack_into("<2sHHIII", b, 0, b"AX", 508, device_id & 0x7FFF, session_id, seq,
                         _om_time(y, mo, d, tot // 3600, tot // 60 % 60, tot % 60))
        struct.pack_into("<HHBBBBhH", b, 18, (accel_n << 13) | ((gyro_n if ax6 else 0) << 10) | 300, 256, 0, 168,
                         rate, 0x62 if ax6 else 0x32, i, per)
        v = np.hstack([gyr_counts[a:a + per], acc_counts[a:a + per]]) if ax6 else acc_counts[a:a + per]
        data = np.ascontiguousarray(v, dtype="<i2").tobytes()
        b[30:30 + len(data)] = data
        struct.pack_into("<H", b, 510, -sum(struct.unpack("<255H", bytes(b[:510]))) & 0xFFFF)
        blocks.append(bytes(b))
    path.write_bytes(b"".join(blocks))


@pytest.mark.parametrize("ax6", [False, True])
def test_cwa_counts_become_m_s2_rad_s_on_the_device_clock(tmp_path, ax6):
    pytest.importorskip("skdh", reason="the CWA reader is the optional extra 'cwa': pip install 'stridelab[cwa]'")
    rng = np.random.default_rng(5)
    n = 1200
    acc = rng.integers(-8000, 8000, (n, 3)).astype(np.int16)
    gyr = rng.integers(-20000, 20000, (n, 3)).astype(np.int16) if ax6 else None
    write_cwa(tmp_path / "wrist.cwa", acc, gyr)
    res = import_paths("cwa", [tmp_path / "wrist.cwa"], tmp_path / "inbox", session={"participant": "P03"})
    assert not res.errors, res.errors
    topics, _, sess = read_mcap(res.written[0])
    t, g, a = _imu(topics, "chest")
    assert len(t) == n
    np.testing.assert_allclose(a, acc.astype(float) / 4096 * G0, rtol=1e-12, atol=1e-12)          # 1/4096 g -> m/s²
    if ax6:
        np.testing.assert_allclose(g, np.deg2rad(gyr.astype(float) * 2000 / 32768), rtol=1e-12)    # deg/s -> rad/s
        assert "accelerometer_only" not in sess
    else:
        assert not g.any() and sess["accelerometer_only"] == "chest"
    # the device clock: 2024-05-01 09:00:00 at sample 0, 100 Hz (skdh's float seconds: < 1 µs off)
    want = 1_714_554_000_000_000_000 + np.arange(n) * 10_000_000
    assert np.abs(t - want).max() < 1000
    assert sess["participant"] == "P03" and sess["kind"] == "free_living" and "/mag/chest" not in topics


def test_bad_cwa_files_one_line_each_nothing_written(tmp_path):
    acc = np.random.default_rng(6).integers(-8000, 8000, (800, 3)).astype(np.int16)
    write_cwa(tmp_path / "good.cwa", acc)
    raw = (tmp_path / "good.cwa").read_bytes()
    flipped = bytearray(raw)
    flipped[1024 + 3 * 512 + 100] ^= 0xFF                   # one sample byte of block 3: its checksum fails
    files = {"flipped.cwa": bytes(flipped), "cut.cwa": raw[:1024 + 2 * 512 + 100], "header.cwa": raw[:1024],
             "text.cwa": b"time,x,y,z\n" * 200}
    for name, b in files.items():
        (tmp_path / name).write_bytes(b)
    inbox = tmp_path / "inbox"
    res = import_paths("cwa", [tmp_path / n for n in files], inbox)
    assert not res.written and len(res.errors) == len(files)
    assert all("\n" not in e for e in res.errors)
    why = dict(zip(files, res.errors))
    assert "flipped.cwa" in why["flipped.cwa"] and "1 of 10 data blocks fail their checksum" in why["flipped.cwa"]
    assert "truncated" in why["cut.cwa"] and "copy it again" in why["cut.cwa"]
    assert "without data blocks" in why["header.cwa"]           # skdh would abort the process on this one
    assert "not an Axivity CWA file" in why["text.cwa"]
    assert not inbox.exists() or not list(inbox.iterdir())


def test_cwa_without_the_optional_extra_is_refused_in_one_line(tmp_path, monkeypatch):
    """scikit-digital-health is the optional extra 'cwa': where it is missing, a sound CWA file is refused with a
    line naming the file and the extra to install, and nothing is written."""
    import sys
    monkeypatch.setitem(sys.modules, "skdh", None)           # import skdh -> ImportError, as where it is absent
    monkeypatch.setitem(sys.modules, "skdh.io", None)
    write_cwa(tmp_path / "wrist.cwa", np.zeros((400, 3), np.int16))
    res = import_paths("cwa", [tmp_path / "wrist.cwa"], tmp_path / "inbox")
    assert not res.written and len(res.errors) == 1 and "\n" not in res.errors[0]
    assert "wrist.cwa" in res.errors[0] and "pip install 'stridelab[cwa]'" in res.errors[0]
    assert not (tmp_path / "inbox").exists() or not list((tmp_path / "inbox").iterdir())


# ---- bad files ------------------------------------------------------------------------------

def test_bad_files_one_line_each_nothing_written(tmp_path):
    (tmp_path / "empty.csv").write_text("")
    (tmp_path / "wrong.csv").write_text("a,b,c\n1,2,3\n")
    (tmp_path / "bin.hdf5").write_bytes(b"\x00" * 100)
    _write_xio(tmp_path / "good.csv")
    inbox = tmp_path / "inbox"
    r = CliRunner().invoke(main, ["import", "xio", str(tmp_path / "empty.csv"), str(tmp_path / "wrong.csv"),
                                  str(tmp_path / "good.csv"), "--inbox", str(inbox), "--json"])
    assert r.exit_code == 1
    out = json.loads(r.stdout)
    assert [p.rsplit("/", 1)[1] for p in out["written"]] == [f"xio-f{T('good.csv')}.mcap"]   # no file name kept
    assert len(out["errors"]) == 2 and all("\n" not in e for e in out["errors"])
    assert "empty.csv" in out["errors"][0] and "wrong.csv" in out["errors"][1] and "missing column" in out["errors"][1]
    res = import_paths("broad", [tmp_path / "bin.hdf5"], inbox)
    assert res.errors and "bin.hdf5" in res.errors[0]
    assert sorted(p.name for p in inbox.iterdir()) == [f"xio-f{T('good.csv')}.mcap"]


def test_bad_session_field_is_refused_before_writing(tmp_path):
    _write_xio(tmp_path / "a.csv")
    res = import_paths("xio", [tmp_path / "a.csv"], tmp_path / "inbox", session={"kind": "party"})
    assert not res.written and "kind 'party'" in res.errors[0] and "--session" in res.errors[0]
    res = import_paths("xio", [tmp_path / "a.csv"], tmp_path / "inbox", session={"start": "yesterday"})
    assert not res.written and "ISO 8601" in res.errors[0]
    r = CliRunner().invoke(main, ["import", "xio", str(tmp_path / "a.csv"), "--session", "participant"])
    assert r.exit_code != 0 and "KEY=VALUE" in r.output


# ---- PyShoe Vicon .mat ----------------------------------------------------------------------

def test_pyshoe_mat_foot_imu_and_vicon_position(tmp_path):
    import scipy.io as sio
    n, fs = 400, 200.0
    rng = np.random.default_rng(6)
    imu = np.column_stack([rng.normal(size=(n, 3)) + [0, 0, 9.81], rng.normal(size=(n, 3))])
    gt = np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0)
    ts = 100.0 + np.arange(n) / fs
    sio.savemat(tmp_path / "2018-02-09-11-16-53.mat", {"imu": imu, "ts": ts[None, :], "gt": gt})
    res = import_paths("pyshoe", [tmp_path], tmp_path / "inbox", study="public")
    topics, _, sess = read_mcap(res.written[0])
    t, g, a = _imu(topics, "foot_right")
    np.testing.assert_array_equal(a, imu[:, :3])
    np.testing.assert_array_equal(g, imu[:, 3:])
    pos = topics["/reference/pose/foot_right"][1][:, :3]
    np.testing.assert_allclose(pos, gt * [1, -1, 1])                      # Vicon y flipped (data README)
    assert t[0] == 1518175013 * 10**9                                     # 2018-02-09T11:16:53Z, from the name
    assert sess["foot_side"] == "unknown" and "Vicon" in sess["reference"]


# ---- Xsens MT Manager text + Voisard events ---------------------------------------------------

def _write_xsens(path, n=300, drop=()):
    rng = np.random.default_rng(7)
    packet = np.array([p for p in range(n) if p not in drop], float)
    v = rng.normal(size=(len(packet), 9))
    with open(path, "w") as f:
        f.write("Acquisition frequency: 100 Hz\n")
        f.write("PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\tMag_X\tMag_Y\tMag_Z\n")
        for p, row in zip(packet, v):
            f.write("\t".join([f"{p:.1f}"] + [f"{x:.6f}" for x in row]) + "\n")
    return packet, np.round(v, 6)


def test_voisard_trial_feet_lower_back_and_events_on_the_packet_grid(tmp_path):
    d = tmp_path / "v"
    d.mkdir()
    pk, v = _write_xsens(d / "3-2_lf.txt", drop=(50, 51))
    _write_xsens(d / "3-2_rf.txt")
    _write_xsens(d / "3-2_lb.txt")
    (d / "3-2.json").write_text(json.dumps({
        "Subject": 3, "Trial": 2, "Age": 30, "Gender": "F", "Height": 170.0, "Weight": 60.0,
        "TrialBoundaries": [10, 280], "UTurnBoundaries": [100, 150],
        "LeftFootEvents": [[60, 90], [160, 190]], "RightFootEvents": [[110, 140]]}))
    res = import_paths("voisard", [d], tmp_path / "inbox", study="public")
    assert not res.errors, res.errors
    topics, events, sess = read_mcap(res.written[0])
    assert sorted(k for k in topics if k.startswith("/imu/")) == ["/imu/foot_left", "/imu/foot_right", "/imu/lower_back"]
    t, g, a = _imu(topics, "foot_left")
    np.testing.assert_allclose(a, v[:, :3], atol=1e-12)
    np.testing.assert_allclose(g, v[:, 3:6], atol=1e-12)
    np.testing.assert_array_equal(t - t[0], (pk * 1e7).astype(np.int64))       # dropped packets keep their gap
    left_ic = sorted(e["t_ns"] - int(t[0]) for e in events if e["type"] == "IC" and e["side"] == "left")
    assert left_ic == [900_000_000, 1_900_000_000]                             # sample 90, 190 of the packet grid
    assert sess["participant"] == "voisard03" and not any(k.startswith("/mag/") for k in topics)


def test_xsens_single_file_placement_from_the_name(tmp_path):
    _write_xsens(tmp_path / "walk_rf.txt")
    _write_xsens(tmp_path / "walk.txt")
    res = import_paths("xsens", [tmp_path], tmp_path / "inbox")
    assert [p.name for p in res.written] == [f"xsens-f{T('walk_rf.txt')}.mcap"]
    assert len(res.errors) == 1 and "walk.txt" in res.errors[0] and "--placement" in res.errors[0]


@pytest.mark.realdata
def test_public_voisard_and_pyshoe_files(tmp_path):
    from stridelab.pipeline.formats.pyshoe import load_pyshoe_trial
    from stridelab.pipeline.formats.xsens_mt import load_voisard_trial
    vd, pd_ = shared_data("voisard_gait"), shared_data("pyshoe_vicon")
    res = import_paths("voisard", [vd / "2-3.json"], tmp_path / "inbox")
    tr = load_voisard_trial(vd, "2-3", packet_grid=False)
    topics, events, _ = read_mcap(res.written[0])
    _, g, _ = _imu(topics, "foot_right")
    np.testing.assert_array_equal(g, tr.right.gyr)
    assert sum(e["type"] == "IC" for e in events) == len(tr.annotation.left_events) + len(tr.annotation.right_events)
    f = sorted(pd_.glob("*.mat"))[0]
    res = import_paths("pyshoe", [f], tmp_path / "inbox")
    p = load_pyshoe_trial(f)
    topics, _, _ = read_mcap(res.written[0])
    np.testing.assert_array_equal(topics["/reference/pose/foot_right"][1][:, :3], p.position)
