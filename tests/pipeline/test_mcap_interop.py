"""Recordings written by the ROS 2 ecosystem's own tools get in bit-equal; files StrideLab writes open
in those tools (issue 13)."""
from __future__ import annotations

from pathlib import Path

import pytest

from stridelab.pipeline import runner
from stridelab.pipeline.formats.mcap_write import write_recording
from tests.corpus import small_recording
from tests.pipeline._interop import (assert_bit_equal, rewrite_with_mcap, rosbags_write, stored, write_mcap_ros2)
from stridelab.warehouse.read import connect_snapshot


def _ingest(wh: Path, files, **kw):
    return runner.run(wh, None, files=[Path(f) for f in files], stages=False, command="ingest", **kw)


def _check_stored(wh: Path, rec, mag=True):
    for pl, x in rec.imu.items():
        assert_bit_equal(stored(wh, pl, "imu"), x.t_ns, x.acc, x.gyr)
        if mag and x.mag is not None:
            assert_bit_equal(stored(wh, pl, "mag"), x.t_ns, mag_ut=(x.mag * 1e-6) * 1e6)


@pytest.mark.parametrize("compression,chunk_size", [("zstd", 64 * 1024), ("lz4", 16 * 1024), ("none", 64 * 1024),
                                                    ("zstd", 1 << 30)])
def test_mcap_ros2_writer_file_is_ingested_bit_equal(tmp_path, compression, chunk_size):
    rec = small_recording(seconds=8.0)
    f = write_mcap_ros2(tmp_path / "ros2.mcap", rec, compression=compression, chunk_size=chunk_size)
    s = _ingest(tmp_path / "wh", [f])
    assert s.ingested == ["ros2.mcap"], s.quarantined
    _check_stored(tmp_path / "wh", rec)



@pytest.mark.parametrize("group_bytes", [40 * 1024, 8 << 20])
def test_chunks_decoded_in_groups_keep_order_and_channels_defined_mid_file(tmp_path, monkeypatch, group_bytes):
    """The reader decodes runs of consecutive chunks as one task and joins each channel's blocks
    (mcap_read.GROUP_BYTES); a channel whose Channel record sits in a chunk in the middle of such a run
    (its first message comes 6 s into the file) and the run boundaries keep every sample, in order."""
    from dataclasses import replace
    from stridelab.pipeline.formats import mcap_read
    monkeypatch.setattr(mcap_read, "GROUP_BYTES", group_bytes)
    seen = []
    task = mcap_read._group_task
    monkeypatch.setattr(mcap_read, "_group_task", lambda bodies, *a: seen.append(len(bodies)) or task(bodies, *a))
    rec = small_recording(seconds=12.0)
    late = rec.imu["shank_left"]
    rec.imu["shank_left"] = replace(late, t_ns=late.t_ns[600:], acc=late.acc[600:], gyr=late.gyr[600:],
                                    mag=late.mag[600:])
    f = write_mcap_ros2(tmp_path / "late.mcap", rec, compression="zstd", chunk_size=16 * 1024)
    s = _ingest(tmp_path / "wh", [f])
    assert s.ingested == ["late.mcap"], s.quarantined
    _check_stored(tmp_path / "wh", rec)
    assert max(seen) > 1 and (len(seen) > 1) == (group_bytes < 1 << 20), seen


def test_unchunked_file_and_schema_channel_only_in_summary(tmp_path):
    """mcap library, no chunks (Schema/Channel at top level) and a file whose messages come before the
    definitions' only other copy, the summary (the definitions are stripped from the data section)."""
    rec = small_recording(seconds=6.0)
    src = write_mcap_ros2(tmp_path / "src.mcap", rec)
    f = rewrite_with_mcap(src, tmp_path / "flat.mcap", chunked=False, compression="none")
    s = _ingest(tmp_path / "wh", [f])
    assert s.ingested == ["flat.mcap"], s.quarantined
    _check_stored(tmp_path / "wh", rec)


@pytest.mark.slow
def test_project_file_rewritten_by_mcap_library_in_another_order_and_compression(tmp_path):
    rec = small_recording(seconds=8.0, session="S02")
    own = write_recording(rec, tmp_path / "own.mcap")
    for name, kw in {"rev_lz4.mcap": dict(compression="lz4", reverse=True),
                     "rev_flat.mcap": dict(chunked=False, compression="none", reverse=True),
                     "zstd_small.mcap": dict(compression="zstd", chunk_size=4096)}.items():
        f = rewrite_with_mcap(own, tmp_path / name, **kw)
        wh = tmp_path / f"wh-{name}"
        s = _ingest(wh, [f])
        assert s.ingested == [name], s.quarantined
        _check_stored(wh, rec)
        con = connect_snapshot(wh)
        n_events = con.execute("SELECT count(*) FROM reference_events").fetchone()[0]
        con.close()
        assert n_events == len(rec.events)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_rosbags_bag_with_custom_data_is_one_recording(tmp_path, storage):
    rec = small_recording(seconds=6.0)
    custom = {f"session.{k}": v for k, v in rec.metadata.items()}
    bag = rosbags_write(tmp_path / "inbox" / "bag1", rec, storage=storage, custom_data=custom)
    s = runner.run(tmp_path / "wh", tmp_path / "inbox", stages=False, command="ingest")
    assert s.ingested == ["bag1"], s.quarantined
    _check_stored(tmp_path / "wh", rec, mag=False)
    assert bag.is_dir()


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_split_bag_is_one_recording(tmp_path, storage):
    rec = small_recording(seconds=6.0)
    custom = {f"session.{k}": v for k, v in rec.metadata.items()}
    bag = rosbags_write(tmp_path / "inbox" / "split", rec, storage=storage, custom_data=custom, parts=3)
    assert len(list(bag.glob("split_*"))) == 3
    s = runner.run(tmp_path / "wh", tmp_path / "inbox", stages=False, command="ingest")
    assert s.ingested == ["split"], s.quarantined
    _check_stored(tmp_path / "wh", rec, mag=False)
    again = runner.run(tmp_path / "wh", tmp_path / "inbox", stages=False, command="ingest")
    assert again.ingested == [] and again.duplicates == ["split"]


def test_bag_mcap_travelling_alone_keeps_its_custom_data(tmp_path):
    """The rosbag2 metadata record inside the .mcap carries custom_data when metadata.yaml is left behind."""
    rec = small_recording(seconds=6.0)
    custom = {f"session.{k}": v for k, v in rec.metadata.items()}
    bag = rosbags_write(tmp_path / "bag", rec, storage="mcap", custom_data=custom)
    alone = next(bag.glob("*.mcap"))
    s = _ingest(tmp_path / "wh", [alone])
    assert s.ingested == [alone.name], s.quarantined
    _check_stored(tmp_path / "wh", rec, mag=False)


def test_db3_without_its_bag_and_a_bag_without_session_are_reported(tmp_path):
    rec = small_recording(seconds=6.0)
    bag = rosbags_write(tmp_path / "inbox" / "nosession", rec, storage="sqlite3")
    loose = tmp_path / "inbox" / "loose.db3"
    loose.write_bytes(next(bag.glob("*.db3")).read_bytes())
    s = runner.run(tmp_path / "wh", tmp_path / "inbox", stages=False, command="ingest")
    assert s.ingested == []
    reasons = " | ".join(s.quarantined)
    assert "nosession: quarantined: no session metadata" in reasons
    assert "loose.db3: quarantined: a .db3 file is read with its bag directory" in reasons


@pytest.mark.slow
def test_every_file_simulate_writes_opens_in_rosbags_and_mcap_ros2(tmp_path):
    """rosbags' AnyReader and mcap_ros2's decoder read every message; Statistics == messages present."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader
    from stridelab.validation.simulate import simulate_to_dir
    # one visit: every kind of file simulate writes (calibration and walking trials with the optical reference and
    # distance sensors, the free-living chest day), at half the messages to decode in pure Python of two visits
    files = simulate_to_dir(tmp_path / "inbox", participants=1, hours=0.05, visits=1)
    mcaps = [Path(f) for f in files if str(f).endswith(".mcap")]
    assert mcaps
    for f in mcaps:
        with open(f, "rb") as fh:
            r = make_reader(fh, decoder_factories=[DecoderFactory()])
            stats = r.get_summary().statistics
            counts: dict[int, int] = {}
            t_min, t_max = None, None
            for _s, ch, msg, dec in r.iter_decoded_messages(log_time_order=False):
                counts[ch.id] = counts.get(ch.id, 0) + 1
                t_min = msg.log_time if t_min is None else min(t_min, msg.log_time)
                t_max = msg.log_time if t_max is None else max(t_max, msg.log_time)
            assert stats.channel_message_counts == counts, f.name
            assert stats.message_count == sum(counts.values())
            assert (stats.message_start_time, stats.message_end_time) == (t_min, t_max), f.name
        with AnyReader([f]) as ar:
            n = 0
            for conn, _t, raw in ar.messages():
                ar.deserialize(raw, conn.msgtype)
                n += 1
            assert n == stats.message_count, f.name

