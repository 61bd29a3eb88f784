"""A small corpus of real MCAP files, good and bad, built by the tests themselves."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from stridelab.estimators.quaternion import quat_from_axis_angle, quat_rotate, quat_conj
from stridelab.estimators.recording import ImuData, PoseData, Recording
from stridelab.pipeline.formats import ros2_cdr
from stridelab.pipeline.formats.mcap_write import ChannelData, recording_channels, write_mcap, write_recording

T0_NS = 1_772_438_400_000_000_000   # 2026-03-02 08:00:00 UTC


def small_recording(seconds: float = 20.0, rate_hz: float = 100.0, seed: int = 0, session: str = "S01",
                    participant: str = "P001", trial: str = "walk-1", placements=("foot_left", "shank_left"),
                    study: str = "testing") -> Recording:
    """IMUs rotating slowly about a tilted axis with gravity and noise: valid, physically consistent."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz)
    t_ns = T0_NS + np.round(np.arange(n) * 1e9 / rate_hz).astype(np.int64)
    imu = {}
    for k, pl in enumerate(placements):
        w = np.array([0.3, -0.2, 0.5 + 0.1 * k])                 # constant body rate, rad/s
        ang = np.linalg.norm(w) * np.arange(n) / rate_hz
        q = quat_from_axis_angle(np.broadcast_to(w / np.linalg.norm(w), (n, 3)), ang)
        g_body = quat_rotate(quat_conj(q), np.array([0.0, 0.0, 9.81]))
        b_body = quat_rotate(quat_conj(q), np.array([0.0, 20.0, -43.0]))
        imu[pl] = ImuData(t_ns.copy(), g_body + rng.normal(0, 0.03, (n, 3)),
                          np.tile(w, (n, 1)) + rng.normal(0, 0.005, (n, 3)), b_body + rng.normal(0, 0.1, (n, 3)))
    poses = {placements[0]: PoseData(t_ns.copy(), np.zeros((n, 3)), np.tile([1.0, 0, 0, 0], (n, 1)))}
    events = [{"t_ns": int(t_ns[100]), "type": "IC", "side": "left", "placement": "foot_left"},
              {"t_ns": int(t_ns[160]), "type": "TC", "side": "left", "placement": "foot_left"}]
    meta = {"study": study, "participant": participant, "session": session, "kind": "lab",
            "protocol": "test", "trial": trial, "timezone": "Europe/Zurich"}
    return Recording(meta, imu=imu, reference_poses=poses, events=events, name=f"{participant}_{trial}")


def _with_imu(rec: Recording, placement: str, **changes) -> Recording:
    imu = dict(rec.imu)
    imu[placement] = replace(imu[placement], **changes)
    return replace(rec, imu=imu)


def build_bad_corpus(d: Path) -> dict[str, Path]:
    """Write one file per kind of bad input; returns name -> path."""
    d.mkdir(parents=True, exist_ok=True)
    good = small_recording()
    out = {}
    out["empty"] = d / "empty.mcap"
    out["empty"].write_bytes(b"")

    full = write_recording(good, d / "full.tmp.mcap").read_bytes()
    (d / "full.tmp.mcap").unlink()
    out["truncated"] = d / "truncated.mcap"
    out["truncated"].write_bytes(full[: len(full) // 2])

    # wrong CRC: change the uncompressed_crc field of the first chunk record
    buf = bytearray(full)
    i = buf.index(bytes([0x06]), 8)          # first record after Header/Schema/Channel records
    pos = 8
    while True:                               # walk the records to find the chunk opcode for sure
        op, ln = buf[pos], int.from_bytes(buf[pos + 1:pos + 9], "little")
        if op == 0x06:
            i = pos
            break
        pos += 9 + ln
    crc_at = i + 9 + 8 + 8 + 8
    buf[crc_at] ^= 0xFF
    out["bad_crc"] = d / "bad_crc.mcap"
    out["bad_crc"].write_bytes(bytes(buf))

    chans = recording_channels(good)
    chans[0] = ChannelData(chans[0].topic, "custom_msgs/msg/FancyImu", "ros2msg", b"float64 x\n", "cdr",
                           chans[0].log_time, chans[0].payload)
    out["unknown_schema"] = write_mcap(d / "unknown_schema.mcap", chans, {"session": good.metadata})
    out["no_session"] = write_mcap(d / "no_session.mcap", recording_channels(good), {})

    # no time base at all: every stamp of a topic repeats one instant with different values
    t = np.full_like(good.imu["foot_left"].t_ns, good.imu["foot_left"].t_ns[0])
    out["no_time_base"] = write_recording(_with_imu(good, "foot_left", t_ns=t, mag=None), d / "no_time_base.mcap")
    acc = good.imu["foot_left"].acc.copy()
    acc[300:305, 1] = np.nan
    acc[900, 2] = np.inf
    out["nan"] = write_recording(_with_imu(good, "foot_left", acc=acc), d / "nan.mcap")
    out["acc_in_g"] = write_recording(_with_imu(good, "foot_left", acc=good.imu["foot_left"].acc / 9.80665),
                                      d / "acc_in_g.mcap")
    gyr_deg = np.degrees(good.imu["foot_left"].gyr) * 40
    out["gyr_in_deg"] = write_recording(_with_imu(good, "foot_left", gyr=gyr_deg), d / "gyr_in_deg.mcap")
    personal = replace(good, metadata=dict(good.metadata, patient_name="Jane Doe"))
    out["personal_data"] = write_recording(personal, d / "personal_data.mcap")
    traversal = replace(good, metadata=dict(good.metadata, participant="../../etc"))
    out["path_traversal"] = write_recording(traversal, d / "path_traversal.mcap")
    return out


def gap_recording() -> Recording:
    """A valid recording with a 10-minute gap in the middle of every IMU stream."""
    rec = small_recording(seconds=20.0, session="S02", trial="gap")
    imu = {}
    for pl, x in rec.imu.items():
        t = x.t_ns.copy()
        t[1000:] += 600 * 10**9
        imu[pl] = replace(x, t_ns=t)
    poses = {pl: replace(p, t_ns=imu[pl].t_ns.copy()) for pl, p in rec.reference_poses.items()}
    return replace(rec, imu=imu, reference_poses=poses, name="P001_gap")
