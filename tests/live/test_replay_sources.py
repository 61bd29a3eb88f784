"""Replay reads what the ingest reads: a rosbag2 bag (MCAP or SQLite storage) replays like the MCAP file of the
same samples; a file that is not a recording is refused with one line naming it."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from stridelab.cli import main


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_rosbag2_bag_replays_like_the_mcap_file(tmp_path, lab_streams, storage):
    from stridelab.estimators.recording import ImuData, Recording
    from stridelab.pipeline.formats.mcap_write import write_recording
    from stridelab.pipeline.live.streams import read_streams
    from tests.pipeline._interop import rosbags_write
    n = 800                                       # 8 s of the walk, 7 IMUs
    rec = Recording(dict(lab_streams.metadata), imu={
        p: ImuData(s.t_ns[:n], s.acc[:n], s.gyr[:n], None) for p, s in lab_streams.sensors.items()}, name="cut")
    mcap = write_recording(rec, tmp_path / "cut.mcap")
    bag = rosbags_write(tmp_path / "bag", rec, storage=storage,
                        custom_data={f"session.{k}": v for k, v in rec.metadata.items()})
    a, b = read_streams(mcap), read_streams(bag)
    assert set(a.sensors) == set(b.sensors) == set(lab_streams.sensors)
    for p in a.sensors:
        np.testing.assert_array_equal(a.sensors[p].t_ns, b.sensors[p].t_ns)
        np.testing.assert_array_equal(a.sensors[p].gyr, b.sensors[p].gyr)
        np.testing.assert_array_equal(a.sensors[p].acc, b.sensors[p].acc)
    r = CliRunner().invoke(main, ["live", "--replay", str(bag), "--speed", "max", "--no-serve", "--no-record",
                                  "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["frames"] == n and out["samples_in"] == 7 * n and sum(out["gaps"].values()) == 0


def test_not_a_recording_is_refused_with_one_line(tmp_path):
    bad = tmp_path / "notes.mcap"
    bad.write_bytes(b"hello, not an MCAP file at all")
    r = CliRunner().invoke(main, ["live", "--replay", str(bad), "--no-serve", "--no-record"])
    assert r.exit_code != 0
    msg = r.output.strip().splitlines()[-1]
    assert "notes.mcap" in msg and "Traceback" not in r.output
    folder = tmp_path / "folder"
    folder.mkdir()
    r = CliRunner().invoke(main, ["live", "--replay", str(folder), "--no-serve", "--no-record"])
    assert r.exit_code != 0 and "not a rosbag2 bag" in r.output
    r = CliRunner().invoke(main, ["live", "--no-serve", "--no-record"])
    assert r.exit_code != 0 and "--replay" in r.output
    r = CliRunner().invoke(main, ["live", "--osc", "knee=9000", "--no-serve", "--no-record"])
    assert r.exit_code != 0 and "PLACEMENT=PORT" in r.output
