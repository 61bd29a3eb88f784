"""The recorder: valid recording-format MCAP while the session runs, after a kill -9, and after a clean close;
it ingests, and the live outputs ride along as String topics the ingest ignores."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks
from stridelab.cli import main


def _check_like_the_ingest_tests(path: Path) -> dict:
    """The checks of tests/pipeline/test_mcap_interop.py (statistics equal the messages present; mcap_ros2 and
    rosbags decode every message) plus the ingest's own reader; returns message counts per topic."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader
    counts: dict[str, int] = {}
    with open(path, "rb") as fh:
        r = make_reader(fh, decoder_factories=[DecoderFactory()])
        stats = r.get_summary().statistics
        per_ch: dict[int, int] = {}
        for _s, ch, _m, _d in r.iter_decoded_messages(log_time_order=False):
            per_ch[ch.id] = per_ch.get(ch.id, 0) + 1
            counts[ch.topic] = counts.get(ch.topic, 0) + 1
        assert stats.channel_message_counts == per_ch
    with AnyReader([path]) as ar:
        n = sum(1 for c, _t, raw in ar.messages() if ar.deserialize(raw, c.msgtype) is not None)
        assert n == sum(per_ch.values())
    res = ReadResult()
    n_imu = sum(len(b.t_ns) for b in iter_blocks(path, res) if b.kind == "imu")
    assert n_imu == sum(v for k, v in counts.items() if k.startswith("/imu/"))
    assert set(res.ignored_topics) == {"/live/joint_angles", "/live/events", "/live/calibration", "/live/standing"}
    return counts


def _live(args):
    return [sys.executable, "-m", "stridelab", "live", *map(str, args)]


@pytest.mark.slow
def test_a_finished_session_is_valid_mcap_and_ingests(tmp_path, lab_files):
    cal, walk = lab_files
    inbox = tmp_path / "inbox"
    r = CliRunner().invoke(main, ["live", "--replay", str(walk), "--calibration", str(cal), "--speed", "max",
                                  "--inbox", str(inbox), "--name", "done", "--no-serve", "--json"])
    assert r.exit_code == 0, r.output
    summary = json.loads(r.stdout.strip().splitlines()[-1])
    path = inbox / "done.mcap"
    assert summary["recording"] == str(path) and not list((inbox / ".live").glob("*"))
    counts = _check_like_the_ingest_tests(path)
    assert counts["/imu/foot_left"] == summary["frames"] == 3000
    assert counts["/live/events"] > 10 and counts["/live/joint_angles"] > 0
    # the live outputs inside: the events equal what the session published
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(path, "rb") as fh:
        ev = [json.loads(d.data) for _s, ch, _m, d in make_reader(fh, decoder_factories=[DecoderFactory()])
              .iter_decoded_messages(topics=["/live/events"])]
    assert {e["type"] for e in ev} == {"IC", "TC"} and all(e["k_detect"] == e["k"] + 1 for e in ev)
    wh = tmp_path / "wh"
    r = CliRunner().invoke(main, ["ingest", str(path), "--warehouse", str(wh), "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["ingested"] == 1 and not out["quarantined"], out
    # live beside offline: the recorded live outputs against the nightly's estimators on the same raw data
    r = CliRunner().invoke(main, ["live", "--compare", str(path), "--calibration", str(cal), "--json"])
    assert r.exit_code == 0, r.output
    agree = json.loads(r.stdout)
    for side in ("left", "right"):
        for typ in ("IC", "TC"):
            m = agree["events"][side][typ]
            assert m["live"] >= 8 and m["matched"] >= 0.9 * max(m["live"], m["offline"]), m
    for key in ("hip_left", "hip_right", "knee_left", "knee_right"):
        assert agree["joints"][key]["rmse_deg"][0] < 5.0, agree["joints"]     # flexion: online vs offline filter


@pytest.mark.slow
def test_kill_9_leaves_a_valid_file_up_to_the_last_chunk_and_recover_moves_it_in(tmp_path, lab_files):
    cal, walk = lab_files
    inbox = tmp_path / "inbox"
    proc = subprocess.Popen(_live(["--replay", walk, "--calibration", cal, "--speed", "1", "--inbox", inbox,
                                   "--name", "crash", "--no-serve"]),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    part = inbox / ".live" / "crash.mcap"
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:          # wait for at least three chunks (about 3 s of samples)
            if part.exists():
                try:       # (a read racing the writer's pwrite can see half of it: only the dead file counts)
                    n = sum(len(b.t_ns) for b in iter_blocks(part, ReadResult()) if b.topic == "/imu/pelvis")
                except ValueError:
                    n = 0
                if n >= 300:
                    break
            if proc.poll() is not None:
                pytest.fail(f"live exited early: {proc.stderr.read()[-2000:]}")
            time.sleep(0.2)
        else:
            pytest.fail("the recording did not reach three chunks within 120 s")
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    assert proc.returncode == -signal.SIGKILL
    assert not (inbox / "crash.mcap").exists()
    blocks = list(iter_blocks(part, ReadResult()))
    t = np.concatenate([b.t_ns for b in blocks if b.topic == "/imu/pelvis"])
    assert len(t) >= 300 and (np.diff(t) > 0).all()
    r = CliRunner().invoke(main, ["live", "--recover", "--inbox", str(inbox)])
    assert r.exit_code == 0 and "moved into the inbox" in r.output, r.output
    wh = tmp_path / "wh"
    r = CliRunner().invoke(main, ["ingest", str(inbox / "crash.mcap"), "--warehouse", str(wh), "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["ingested"] == 1 and not out["quarantined"], out


def test_a_torn_file_is_refused_by_recover_and_left_in_place(tmp_path):
    live = tmp_path / "inbox" / ".live"
    live.mkdir(parents=True)
    (live / "torn.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\x01" * 40)
    from stridelab.pipeline.live.recorder import recover
    [(p, outcome)] = recover(tmp_path / "inbox")
    assert p == live / "torn.mcap" and outcome.startswith("left in place") and p.exists()


def test_a_file_cut_mid_chunk_is_repaired_to_its_last_complete_chunk(tmp_path):
    """What a short write at a kill could leave: half of a new chunk over the old tail. recover() cuts it off,
    closes the file and moves it in, with every sample of the complete chunks."""
    from stridelab.pipeline.live.recorder import McapRecorder, recover
    rec = McapRecorder(tmp_path / "inbox", "torn", ["pelvis"], {"study": "demo", "participant": "P001",
                                                                 "session": "P001-live-x", "kind": "lab"})
    t0 = 1_772_611_310_000_000_000
    for i in range(250):                                   # two complete 1-s chunks, the rest pending
        t = np.array([t0 + i * 10_000_000])
        rec.add_imu("pelvis", t, t, np.zeros((1, 3)), np.array([[0.0, 0.0, 9.81]]))
    size = rec.path.stat().st_size
    good = sum(len(b.t_ns) for b in iter_blocks(rec.path, ReadResult()))
    assert 150 < good < 250
    rec.flush()                                            # a third chunk ...
    whole = rec.path.read_bytes()
    os.close(rec._fd)
    tail = 13 + 29 + 8                                     # DataEnd, Footer, magic: where the new chunk went
    assert len(whole) > size + 300
    rec.path.write_bytes(whole[:size - tail + 300])        # ... of which only 300 bytes reached the disk
    with pytest.raises(ValueError):
        list(iter_blocks(rec.path, ReadResult()))
    [(p, outcome)] = recover(tmp_path / "inbox")
    assert outcome == "moved into the inbox", outcome
    assert sum(len(b.t_ns) for b in iter_blocks(p, ReadResult())) == good
