"""Odd inbox entries and file names (issue #47): skipped entries listed with the reason, long names and names with
newlines or terminal escape codes ingested without a traceback or a forged log line."""
from __future__ import annotations

import json
import os

import pytest

from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.pipeline.privacy import stored_name
from tests.corpus import small_recording
from tests.pipeline.test_runner import cli
from stridelab.warehouse.read import connect_snapshot

FORGED = "evil\nrun 20990101T000000Z-abcdef: 99 ingested\x1b[2J"


@pytest.mark.slow
def test_odd_inbox_entries_are_listed_with_the_reason_and_odd_names_forge_nothing(tmp_path):
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    long_name = "L" * 249 + ".mcap"                  # 254 bytes: its sidecar name would pass 255
    short = write_recording(small_recording(seconds=3.0, seed=1, session="S01", trial="t1"), inbox / "short.mcap")
    short.rename(inbox / long_name)          # (our writer's temporary name would pass 255 bytes)
    write_recording(small_recording(seconds=3.0, seed=2, session="S02", trial="t2"), inbox / f"{FORGED}.mcap")
    os.symlink(tmp_path / "missing.mcap", inbox / "dangling.mcap")
    os.symlink(inbox / "loop.mcap", inbox / "loop.mcap")
    (tmp_path / "elsewhere").mkdir()
    os.symlink(tmp_path / "elsewhere", inbox / "linked_dir")
    os.mkfifo(inbox / "fifo.mcap")
    os.symlink("/dev/null", inbox / "device.mcap")
    (inbox / "folder.mcap").mkdir()
    r = cli("ingest", inbox, "--warehouse", tmp_path / "wh", "--json")
    assert "Traceback" not in r.stderr, r.stderr
    out = json.loads(r.stdout)
    assert out["ingested"] == 2, r.stderr
    reasons = {os.path.basename(s.split(": ")[0]): s.split(": ", 1)[1] for s in out["skipped"]}
    assert reasons == {
        "dangling.mcap": "a dangling symbolic link (its target is missing)",
        "loop.mcap": "a symbolic link loop",
        "linked_dir": "a symbolic link to a directory: not followed (copy or move the folder into the inbox)",
        "fifo.mcap": "a FIFO, not a regular file",
        "device.mcap": "a device, not a regular file",
        "folder.mcap": "a directory with a recording's name but no metadata.yaml: not a recording"}
    r = cli("ingest", inbox, "--warehouse", tmp_path / "wh2")
    assert r.returncode == 0, r.stderr
    assert not any(line.startswith("run 20990101") for line in r.stderr.splitlines())    # no forged line
    assert "\x1b" not in r.stderr and "evil\\nrun" in r.stderr.replace("\\\\", "\\")
    assert "skipped:" in r.stderr and "fifo.mcap: a FIFO" in r.stderr
    con = connect_snapshot(tmp_path / "wh2")
    stored = sorted(n for (n,) in con.execute("SELECT file_name FROM recordings").fetchall())
    assert stored == sorted([stored_name(long_name), stored_name(f"{FORGED}.mcap")])   # keyed hashes of the
    assert all(n.isascii() and n.isprintable() and len(n) < 64 for n in stored)       # whole names (privacy)
    con.close()


def test_our_writer_takes_output_names_up_to_255_bytes(tmp_path):
    """``write_mcap`` writes a temporary file beside the output first: its name must not pass 255 bytes when the
    output's does not (issue #47: names above ~240 bytes failed with 'File name too long')."""
    from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks
    for name in ("Ł" * 120 + ".mcap", "L" * 250 + ".mcap"):          # 245 and 255 bytes
        assert len(os.fsencode(name)) <= 255
        out = write_recording(small_recording(seconds=2.0), tmp_path / name)
        assert out.name == name and [p.name for p in tmp_path.iterdir()] == [name]       # no temporary left
        res = ReadResult()
        assert sum(len(b.t_ns) for b in iter_blocks(out, res) if b.kind == "imu") == 400   # 2 IMUs, 2 s at 100 Hz
        out.unlink()
