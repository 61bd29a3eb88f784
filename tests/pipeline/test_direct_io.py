"""Large series files that are not in the page cache are read with O_DIRECT (warehouse/direct_io.py): the bytes
and the decoded columns are exactly those of a buffered read, and a refusal of O_DIRECT falls back to buffered."""
from __future__ import annotations

import errno
import io
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from warehouse import direct_io, read
from warehouse.direct_io import ALIGN, DirectFile, cached_fraction, open_for_read
from tests.pipeline._page_cache import uncache as _uncache

pytestmark = pytest.mark.skipif(not getattr(os, "O_DIRECT", 0), reason="the platform has no O_DIRECT")


@pytest.fixture
def data_file(tmp_path):
    p = tmp_path / "blob.bin"
    data = np.random.default_rng(1).integers(0, 256, 5 * ALIGN + 1234, dtype=np.uint8).tobytes()
    p.write_bytes(data)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_DIRECT)
    except OSError:
        pytest.skip(f"{tmp_path} refuses O_DIRECT")
    f = DirectFile(p, fd)
    yield f, data
    f.close()


def test_reads_at_unaligned_offsets_are_the_file_bytes(data_file):
    f, data = data_file
    rng = np.random.default_rng(2)
    for off, n in [(0, 1), (1, ALIGN), (ALIGN - 1, 2), (3 * ALIGN, ALIGN), (777, 3 * ALIGN + 5),
                   (len(data) - 10, 100), (len(data), 5)] + [tuple(rng.integers(0, len(data), 2)) for _ in range(50)]:
        f.seek(int(off))
        got = f.read(int(n))
        assert bytes(got) == data[off:off + n], (off, n)
        assert f.tell() == min(len(data), off + n)
        assert got.readonly
    f.seek(-7, io.SEEK_END)
    assert bytes(f.read()) == data[-7:]
    f.seek(100)
    f.seek(50, io.SEEK_CUR)
    buf = bytearray(10)
    assert f.readinto(buf) == 10 and bytes(buf) == data[150:160]
    assert f.size() == len(data) and f.direct


def test_einval_at_a_read_goes_on_buffered(data_file, monkeypatch):
    f, data = data_file
    real = os.preadv
    calls = []

    def refuse_direct(fd, bufs, off):
        calls.append(f.direct)
        if f.direct:
            raise OSError(errno.EINVAL, "Invalid argument")
        return real(fd, bufs, off)

    monkeypatch.setattr(direct_io.os, "preadv", refuse_direct)
    f.seek(ALIGN + 3)
    assert bytes(f.read(2 * ALIGN)) == data[ALIGN + 3:3 * ALIGN + 3]
    assert not f.direct and calls == [True, False]
    assert bytes(f.read(10)) == data[3 * ALIGN + 3:3 * ALIGN + 13]


def test_open_for_read_chooses_direct_only_for_large_uncached_files(tmp_path):
    p = tmp_path / "big.bin"
    p.write_bytes(os.urandom(64 * ALIGN))
    assert open_for_read(p, 10 ** 9) == p                   # under the size: a path, pyarrow reads buffered
    missing = tmp_path / "missing.bin"
    assert open_for_read(missing, 0) == missing              # pyarrow reports it
    with open(p, "rb") as fh:
        frac = cached_fraction(fh.fileno(), p.stat().st_size)
    if frac is None:
        pytest.skip("no cachestat(2) on this kernel: the cached fraction is unknown")
    fh = open(p, "rb")
    fh.read()                                                # now cached
    fh.close()
    assert open_for_read(p, 0) == p
    _uncache(p)
    src = open_for_read(p, 0)
    try:
        assert isinstance(src, DirectFile) or src == p       # p: the file system refuses O_DIRECT
        if isinstance(src, DirectFile):
            assert bytes(src.read()) == p.read_bytes()
    finally:
        if isinstance(src, DirectFile):
            src.close()


def test_a_series_read_direct_equals_the_buffered_read(tmp_path, monkeypatch):
    rng = np.random.default_rng(3)
    n = 300_000
    x = rng.normal(size=(n, 3))
    t = np.arange(n, dtype=np.int64) * 10_000_000
    pq.write_table(pa.table({"t_ns": t, "acc_x": x[:, 0], "acc_y": x[:, 1], "acc_z": x[:, 2]}),
                   tmp_path / "s.parquet", row_group_size=70_000, compression="lz4")
    cols = ("acc_x", "acc_y", "acc_z")
    ranges = ((0, n), (65_000, 211_111), (70_000, 140_000), (n - 1, n))
    buffered = [read.read_column_range(tmp_path, "s.parquet", cols, a, b) for a, b in ranges]
    opened = []
    real_open = read.open_for_read

    def spy(path, min_bytes):
        src = real_open(path, min_bytes)
        opened.append(src)
        return src

    monkeypatch.setattr(read, "UNCACHE_BYTES", 0)
    monkeypatch.setattr(read, "open_for_read", spy)
    _uncache(tmp_path / "s.parquet")
    for (a, b), want in zip(ranges, buffered):
        _uncache(tmp_path / "s.parquet")
        got = read.read_column_range(tmp_path, "s.parquet", cols, a, b)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(got, x[a:b])
    np.testing.assert_array_equal(read.read_column_range(tmp_path, "s.parquet", ("t_ns",), 5, 9, dtype=np.int64),
                                  t[5:9])
    if not any(isinstance(s, DirectFile) for s in opened):
        pytest.skip("O_DIRECT or cachestat(2) unavailable here: only the buffered path ran")
    assert all(s.closed for s in opened if isinstance(s, DirectFile))
