"""Inbox files are read past the page cache when they are not cached (pipeline/formats/direct_read.py), large
series files leave the page cache once committed (warehouse/store.py), and neither changes a byte read or
stored. Block sizes are shrunk so that small test files take the O_DIRECT path."""
from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from stridelab.pipeline import ingest
from stridelab.pipeline.formats import direct_read
from stridelab.pipeline.formats.direct_read import SequentialReader, cached_fraction
from stridelab.pipeline.formats.mcap_read import ReadResult, iter_blocks
from stridelab.pipeline.formats.mcap_write import write_recording
from stridelab.warehouse import store
from tests.corpus import small_recording
from tests.pipeline._page_cache import uncache as _uncache

SMALL_BLOCK = 64 << 10


def _odirect_works(d: Path) -> bool:
    p = d / "probe"
    p.write_bytes(b"\0" * 8192)
    try:
        os.close(os.open(p, os.O_RDONLY | os.O_DIRECT))
        return True
    except OSError:
        return False


@pytest.fixture
def small_blocks(monkeypatch, tmp_path):
    if not _odirect_works(tmp_path):
        pytest.skip(f"the file system of {tmp_path} refuses O_DIRECT")
    monkeypatch.setattr(direct_read, "BLOCK", SMALL_BLOCK)


def _read_all(r: SequentialReader, sizes) -> bytes:
    out = bytearray()
    k = 0
    while True:
        buf = bytearray(sizes[k % len(sizes)])
        n = r.readinto(buf)
        out += buf[:n]
        k += 1
        if n < len(buf):
            return bytes(out)


@pytest.mark.parametrize("length", [3 * SMALL_BLOCK, 5 * SMALL_BLOCK + 4097, 2 * SMALL_BLOCK + 1])
def test_direct_reads_return_exactly_the_file(tmp_path, small_blocks, length):
    data = np.random.default_rng(length).integers(0, 256, length, dtype=np.uint8).tobytes()
    p = tmp_path / "f.bin"
    p.write_bytes(data)
    with SequentialReader(p, length, force=True) as r:
        assert r.direct
        got = _read_all(r, [7, SMALL_BLOCK, 3 * SMALL_BLOCK + 11, 1])
        assert r.tell() == length and r.readinto(bytearray(10)) == 0
    assert got == data
    with SequentialReader(p, length, force=True) as r:
        head = bytearray(1000)
        assert r.readinto(head) == 1000
        assert head + r.read() == data


def test_a_file_truncated_before_it_is_read_gives_a_short_read(tmp_path, small_blocks):
    data = os.urandom(4 * SMALL_BLOCK)
    p = tmp_path / "f.bin"
    p.write_bytes(data)
    os.truncate(p, SMALL_BLOCK + 100)               # the size the caller knows is the old one
    with SequentialReader(p, len(data), force=True) as r:
        assert r.direct
        got = _read_all(r, [SMALL_BLOCK // 2])
    assert got == data[:SMALL_BLOCK + 100]


def test_o_direct_refused_at_open_or_at_read_falls_back_to_buffered(tmp_path, small_blocks, monkeypatch):
    data = os.urandom(3 * SMALL_BLOCK + 5)
    p = tmp_path / "f.bin"
    p.write_bytes(data)
    real_open = os.open

    def no_direct_open(path, flags, *a):
        if flags & os.O_DIRECT:
            raise OSError(errno.EINVAL, "O_DIRECT not supported")
        return real_open(path, flags, *a)

    with monkeypatch.context() as m:
        m.setattr(os, "open", no_direct_open)
        with SequentialReader(p, len(data), force=True) as r:
            assert not r.direct
            assert _read_all(r, [SMALL_BLOCK]) == data

    calls = []
    real_preadv = os.preadv

    def einval_after_one_block(fd, bufs, off, *a):
        calls.append(off)
        if off > 0:
            raise OSError(errno.EINVAL, "Invalid argument")
        return real_preadv(fd, bufs, off, *a)

    monkeypatch.setattr(os, "preadv", einval_after_one_block)
    with SequentialReader(p, len(data), force=True) as r:
        got = _read_all(r, [SMALL_BLOCK // 3])
        assert not r.direct                          # went on buffered from where it stood
    assert got == data and calls[:2] == [0, SMALL_BLOCK]


def test_other_read_errors_are_raised(tmp_path, small_blocks, monkeypatch):
    p = tmp_path / "f.bin"
    p.write_bytes(os.urandom(3 * SMALL_BLOCK))

    def eio(*a):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(os, "preadv", eio)
    with SequentialReader(p, 3 * SMALL_BLOCK, force=True) as r, pytest.raises(OSError) as e:
        r.readinto(bytearray(100))
    assert e.value.errno == errno.EIO


def test_the_path_follows_what_the_page_cache_holds(tmp_path, small_blocks):
    p = tmp_path / "f.bin"
    p.write_bytes(os.urandom(4 * SMALL_BLOCK))
    fd = os.open(p, os.O_RDONLY)
    try:
        frac = cached_fraction(fd, 4 * SMALL_BLOCK)
    finally:
        os.close(fd)
    if frac is None:
        pytest.skip("mincore(2) is not available here")
    assert frac > 0.9                               # just written: cached
    with SequentialReader(p, 4 * SMALL_BLOCK) as r:
        assert not r.direct
    _uncache(p)
    with SequentialReader(p, 4 * SMALL_BLOCK) as r:
        assert r.direct
    q = tmp_path / "small.bin"                       # under two blocks: always buffered
    q.write_bytes(os.urandom(SMALL_BLOCK))
    _uncache(q)
    with SequentialReader(q, SMALL_BLOCK) as r:
        assert not r.direct


def _blocks(path):
    res = ReadResult()
    out = [(b.topic, b.kind, b.t_ns.tobytes(), b.log_ns.tobytes(),
            repr(b.values) if isinstance(b.values, list) else b.values.tobytes())
           for b in iter_blocks(path, res)]
    return out, res.sha256


def test_an_uncached_mcap_decodes_and_hashes_as_a_cached_one(tmp_path, small_blocks, monkeypatch):
    f = write_recording(small_recording(seconds=30.0), tmp_path / "rec.mcap")
    assert f.stat().st_size > 4 * SMALL_BLOCK
    monkeypatch.setattr(direct_read, "CACHED_FRACTION", -1.0)       # always buffered
    buffered = _blocks(f)
    seen = []
    real = SequentialReader.__init__

    def spy(self, *a, **k):
        real(self, *a, **k)
        seen.append(self.direct)

    monkeypatch.setattr(SequentialReader, "__init__", spy)
    monkeypatch.setattr(direct_read, "CACHED_FRACTION", 2.0)        # always direct
    assert _blocks(f) == buffered and seen == [True]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    p = ingest.prepare(cut, tmp_path / "wh")
    assert p.status == "quarantined" and "truncated" in p.reason and seen[-1] is True


def test_large_committed_series_leave_the_page_cache(tmp_path, monkeypatch):
    if cached_fraction(os.open(__file__, os.O_RDONLY), 1) is None:
        pytest.skip("mincore(2) is not available here")
    monkeypatch.setattr(store, "UNCACHE_BYTES", 1 << 20)
    n = 400_000
    table = pa.table({"t_ns": pa.array(np.arange(n, dtype=np.int64)),
                      "x": pa.array(np.random.default_rng(0).normal(size=n))})
    big = store.write_table(tmp_path, "series/big.parquet", table)
    small = store.write_table(tmp_path, "series/small.parquet", table.slice(0, 1000))

    def frac(rel):
        fd = os.open(tmp_path / rel, os.O_RDONLY)
        try:
            return cached_fraction(fd, os.fstat(fd).st_size)
        finally:
            os.close(fd)

    assert (tmp_path / big).stat().st_size > 1 << 20
    assert frac(big) < 0.1 and frac(small) > 0.9
    assert store.read_table(tmp_path, big).equals(table)
