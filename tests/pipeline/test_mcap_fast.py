"""The MCAP reader's fast path (pipeline/formats/mcap_fast.py) decodes exactly what the general path decodes,
takes the files the pipeline meets, and hands anything unusual to the general path."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.pipeline.formats import mcap_fast, mcap_read
from tests.corpus import small_recording
from tests.pipeline._interop import write_mcap_ros2
from tests.pipeline._lab import write_lab_session


def _read(path, fast: bool, monkeypatch) -> tuple[dict, mcap_read.ReadResult, list]:
    """Per topic: concatenated stamps, log times and values (events: their dicts); the read result; and for each
    group, whether the fast path decoded it."""
    monkeypatch.setattr(mcap_read, "FAST_PATH", fast)
    taken = []
    result = mcap_fast.GroupDecoder.result
    monkeypatch.setattr(mcap_fast.GroupDecoder, "result", lambda self: taken.append(self.ok) or result(self))
    res = mcap_read.ReadResult()
    parts: dict[str, list] = {}
    for b in mcap_read.iter_blocks(path, res):
        parts.setdefault(b.topic, []).append(b)
    out = {}
    for topic, bs in parts.items():
        if bs[0].kind == "events":
            out[topic] = [v for b in bs for v in b.values]
        else:
            out[topic] = (np.concatenate([b.t_ns for b in bs]), np.concatenate([b.log_ns for b in bs]),
                          np.concatenate([b.values for b in bs]))
    return out, res, taken


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for topic in a:
        if isinstance(a[topic], list):
            assert a[topic] == b[topic], topic
            continue
        for x, y in zip(a[topic], b[topic]):          # bit for bit (NaN payloads included)
            assert x.shape == y.shape and x.dtype == y.dtype, topic
            assert np.ascontiguousarray(x).tobytes() == np.ascontiguousarray(y).tobytes(), topic


@pytest.mark.slow
def test_lab_files_with_imu_mag_poses_events_and_ranges_decode_as_the_general_path(tmp_path, monkeypatch):
    files, _ = write_lab_session(tmp_path, distance_sensors=True, optical_reference=True)
    kinds = set()
    for f in files:
        fast, res_f, taken = _read(f, True, monkeypatch)
        slow, res_s, _ = _read(f, False, monkeypatch)
        _assert_same(fast, slow)
        assert res_f.message_counts == res_s.message_counts and res_f.sha256 == res_s.sha256
        assert taken and all(taken), f"{f.name}: a group left the fast path: {taken}"
        kinds |= {t.kind for t in res_f.topics.values()}
    assert {"imu", "mag", "reference_pose", "events", "range"} <= kinds, kinds


@pytest.mark.parametrize("chunk_size", [16 * 1024, 64 * 1024])
def test_a_mcap_ros2_file_with_definitions_inside_chunks_decodes_as_the_general_path(tmp_path, monkeypatch,
                                                                                      chunk_size):
    """mcap_ros2 puts Schema and Channel records inside the chunks: those groups take the general path, the
    others the fast one, with the same samples (one group in flight at a time, so the definitions of the first
    are registered before the next starts, as in a large file)."""
    monkeypatch.setattr(mcap_read, "GROUP_BYTES", 4 * chunk_size)
    monkeypatch.setattr(mcap_read, "MAX_IN_FLIGHT_BYTES", 1)
    f = write_mcap_ros2(tmp_path / "ros2.mcap", small_recording(seconds=30.0), chunk_size=chunk_size)
    fast, res_f, taken = _read(f, True, monkeypatch)
    slow, res_s, _ = _read(f, False, monkeypatch)
    _assert_same(fast, slow)
    assert res_f.message_counts == res_s.message_counts
    assert taken[0] is False and True in taken, taken


def test_a_message_that_does_not_fit_its_schema_leaves_the_fast_path_with_the_general_error(tmp_path):
    """The kernel refuses a chunk whose message is shorter than the Imu layout (status 1), so the general path
    decodes it and reports what is wrong."""
    plan = mcap_fast.make_plan({1: (37, np.array([13, 14, 15, 25, 26, 27]))})
    payload = b"\x00\x01\x00\x00" + (5).to_bytes(4, "little") + (7).to_bytes(4, "little") + \
        (1).to_bytes(4, "little") + b"\x00" + b"\x00" * 3 + b"\x00" * 8 * 36            # one double short
    record = bytes([5]) + (22 + len(payload)).to_bytes(8, "little") + (1).to_bytes(2, "little") + \
        (0).to_bytes(4, "little") + (123).to_bytes(8, "little") * 2 + payload
    dec = mcap_fast.GroupDecoder(plan, len(record))
    assert not dec.add(record) and dec.result() is None
    ok = bytes([5]) + (22 + len(payload) + 8).to_bytes(8, "little") + record[9:] + b"\x00" * 8
    dec = mcap_fast.GroupDecoder(plan, len(ok))
    assert dec.add(ok)
    (t, log, v), = dec.result()[0].values()
    assert t.tolist() == [5_000_000_007] and log.tolist() == [123] and v.shape == (1, 6)
