"""Recovery of truncated and damaged MCAP files (issue #47): every complete, CRC-valid chunk kept, what was lost
reported. Files by mcap_ros2's writer; the complete-chunk maximum from the mcap library's own reading of the
intact file (its chunk index), not from the code under test."""
from __future__ import annotations

import io
import json

import numpy as np
import pytest

from tests.corpus import small_recording
from tests.pipeline._interop import IMU_DEF, imu_dict
from tests.pipeline.test_runner import cli
from stridelab.warehouse.read import connect_snapshot


def _write(path, rec, *, chunk_size=16 * 1024):
    """mcap_ros2's writer; the session record first (a logger writes it when it starts)."""
    from mcap_ros2.writer import Writer
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size)
        w.add_metadata("session", dict(rec.metadata))
        s = w.register_msgdef("sensor_msgs/msg/Imu", IMU_DEF)
        msgs = []
        for pl, x in rec.imu.items():
            for i, t in enumerate(x.t_ns.tolist()):
                msgs.append((t, f"/imu/{pl}", imu_dict(t, x.acc[i], x.gyr[i], pl)))
        msgs.sort(key=lambda m: m[0])
        for k, (t, topic, msg) in enumerate(msgs):
            w.write_message(topic, s, msg, log_time=t, publish_time=t, sequence=k)
        w.finish()
    return path


def _chunks(path):
    """(end offset, IMU messages) of every chunk, by the mcap library (chunk index + its stream reader)."""
    from mcap.reader import make_reader
    from mcap.exceptions import EndOfFile
    from mcap.records import Message
    from mcap.stream_reader import StreamReader
    data = path.read_bytes()
    with open(path, "rb") as f:
        idx = make_reader(f).get_summary().chunk_indexes
    out = []
    for ci in sorted(idx, key=lambda c: c.chunk_start_offset):
        a, b = ci.chunk_start_offset, ci.chunk_start_offset + ci.chunk_length
        n = 0
        try:
            for r in StreamReader(io.BytesIO(data[a:b]), skip_magic=True).records:
                n += isinstance(r, Message)
        except EndOfFile:                         # the slice holds the one chunk record, no footer
            pass
        out.append((b, n))
    return out


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    rec = small_recording(seconds=30.0, placements=("foot_left", "shank_left"))
    f = _write(d / "walk.mcap", rec)
    return f, _chunks(f)


def test_truncated_files_at_20_offsets_keep_every_complete_chunk(recording, tmp_path):
    from stridelab.pipeline.recover import recover
    f, chunks = recording
    data = f.read_bytes()
    assert len(chunks) >= 10
    offsets = np.linspace(chunks[0][0] - 100, len(data) - 1, 20).astype(int)
    got, best = [], []
    for k, off in enumerate(offsets):
        cut = tmp_path / f"cut{k}.mcap"
        cut.write_bytes(data[:off])
        rep = recover(cut, tmp_path / f"cut{k}.recovered.mcap")
        got.append(rep.messages_kept)
        best.append(sum(n for end, n in chunks if end <= off))
        assert rep.broken_at is not None and "truncated" in rep.summary() or off >= chunks[-1][0]
    assert got == best
    print(f"\nrecovered {sum(got)} of {sum(best)} samples (complete-chunk maximum) at 20 offsets")


def test_a_chunk_with_a_bad_crc_is_skipped_and_the_rest_kept(recording, tmp_path):
    from stridelab.pipeline.recover import recover
    f, chunks = recording
    b = bytearray(f.read_bytes())
    end3, n3 = chunks[3]
    b[end3 - 200] ^= 0xFF                                 # inside chunk 3's compressed data
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(b))
    rep = recover(bad, tmp_path / "bad.recovered.mcap")
    total = sum(n for _, n in chunks)
    assert rep.chunks_lost == 1 and rep.messages_kept == total - n3
    (a, b, why), = rep.lost_ranges                      # its time range from its header; its count only if it
    assert rep.kept_start_ns < a <= b < rep.kept_end_ns and "a chunk at byte" in why   # still decompresses
    assert rep.messages_lost in (None, n3)


@pytest.mark.slow
def test_ingest_recover_stores_what_is_intact_and_says_what_was_lost(recording, tmp_path):
    f, chunks = recording
    data = f.read_bytes()
    off = (chunks[5][0] + chunks[6][0]) // 2
    cut = tmp_path / "logger.mcap"
    cut.write_bytes(data[:off])
    wh = tmp_path / "wh"
    r = cli("ingest", cut, "--warehouse", wh)
    assert r.returncode == 1 and "truncated" in r.stderr                # refused whole without --recover
    r = cli("ingest", cut, "--warehouse", wh, "--recover", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["ingested"] == 1
    con = connect_snapshot(wh)
    n = con.execute("SELECT sum(n_samples) FROM sensors WHERE kind = 'imu'").fetchall()[0][0]
    msgs = [m for (m,) in con.execute("SELECT message FROM recording_issues").fetchall()]
    con.close()
    assert n == sum(k for end, k in chunks if end <= off)
    assert any("recovered from a damaged file" in m and "truncated" in m for m in msgs), msgs
    r = cli("repair", cut, "--out", tmp_path / "out", "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["files"][0]["messages_kept"] == n
