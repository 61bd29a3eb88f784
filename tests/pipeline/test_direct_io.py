"""Large series files that are not in the page cache are read with O_DIRECT (warehouse/direct_io.py): the bytes
and the decoded columns are exactly those of a buffered read, and a refusal of O_DIRECT falls back to buffered."""
from __future__ import annotations

import errno
import io
import os

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from stridelab.warehouse import direct_io, read
from stridelab.warehouse.direct_io import ALIGN, DirectFile, DirectWriteFile, cached_fraction, open_for_read
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
        pytest.skip("no mincore(2) here: the cached fraction is unknown")
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
        pytest.skip("O_DIRECT or mincore(2) unavailable here: only the buffered path ran")
    assert all(s.closed for s in opened if isinstance(s, DirectFile))


# ---- writes past the page cache (DirectWriteFile, used by stridelab.warehouse.store.SeriesWriter) -------------------------

def _pieces(data: bytes, rng) -> list[bytes]:
    """``data`` cut at random places (pieces of 1 byte to 3 blocks), as a writer hands it over."""
    out, i = [], 0
    while i < len(data):
        k = int(rng.integers(1, 3 * 4 * ALIGN))
        out.append(data[i:i + k])
        i += k
    return out


def _direct_refused(tmp_path) -> bool:
    probe = tmp_path / ".probe"
    probe.write_bytes(b"")
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_DIRECT))
    except OSError:
        return True
    finally:
        probe.unlink()
    return False


@pytest.mark.parametrize("size", [0, 1, 4 * ALIGN - 1, 4 * ALIGN, 4 * ALIGN + 1, 13 * 4 * ALIGN + 777])
def test_a_direct_write_is_the_bytes_written(tmp_path, size):
    """Blocks of 4 * ALIGN: a file below one block is written buffered at close; a larger one goes past the page
    cache, block by block, and its tail is padded and truncated away."""
    data = np.random.default_rng(size).integers(0, 256, size, dtype=np.uint8).tobytes()
    f = DirectWriteFile(tmp_path / "out.bin", block=4 * ALIGN)
    for piece in _pieces(data, np.random.default_rng(1)):
        assert f.write(piece) == len(piece)
    assert f.tell() == size
    f.close()
    f.close()                                            # idempotent
    assert (tmp_path / "out.bin").read_bytes() == data
    if size >= 4 * ALIGN and not _direct_refused(tmp_path):
        assert f.direct
    if size < 4 * ALIGN:
        assert not f.direct


def test_a_direct_write_leaves_the_file_out_of_the_page_cache(tmp_path):
    if _direct_refused(tmp_path):
        pytest.skip(f"{tmp_path} refuses O_DIRECT")
    data = np.random.default_rng(5).integers(0, 256, 64 * ALIGN + 100, dtype=np.uint8).tobytes()
    with DirectWriteFile(tmp_path / "out.bin", block=8 * ALIGN) as f:
        f.write(data)
    fd = os.open(tmp_path / "out.bin", os.O_RDONLY)
    try:
        frac = cached_fraction(fd, len(data))
    finally:
        os.close(fd)
    if frac is None:
        pytest.skip("mincore(2) unavailable here")
    assert frac <= 1 / 8                                 # the tail block at most (64 blocks went direct)
    assert (tmp_path / "out.bin").read_bytes() == data


def test_einval_at_a_write_or_a_refused_open_goes_on_buffered(tmp_path, monkeypatch):
    data = np.random.default_rng(6).integers(0, 256, 10 * 4 * ALIGN + 5, dtype=np.uint8).tobytes()
    real_pwrite, calls = os.pwrite, []

    def pwrite(fd, buf, off):
        calls.append(fd)
        if len(calls) == 3:                              # the third block: a file system that refuses late
            raise OSError(errno.EINVAL, "Invalid argument")
        return real_pwrite(fd, buf, off)

    monkeypatch.setattr(direct_io.os, "pwrite", pwrite)
    with DirectWriteFile(tmp_path / "late.bin", block=4 * ALIGN) as f:
        f.write(data)
    assert (tmp_path / "late.bin").read_bytes() == data

    real_open = os.open

    def no_direct(path, flags, *a):
        if flags & os.O_DIRECT:
            raise OSError(errno.EINVAL, "Invalid argument")
        return real_open(path, flags, *a)

    monkeypatch.setattr(direct_io.os, "open", no_direct)
    with DirectWriteFile(tmp_path / "never.bin", block=4 * ALIGN) as f:
        for piece in _pieces(data, np.random.default_rng(7)):
            f.write(piece)
    assert not f.direct
    assert (tmp_path / "never.bin").read_bytes() == data


def test_a_disk_that_stops_taking_blocks_sends_the_rest_of_the_file_through_the_page_cache(tmp_path, monkeypatch):
    if _direct_refused(tmp_path):
        pytest.skip(f"{tmp_path} refuses O_DIRECT")
    import threading
    import time
    monkeypatch.setattr(direct_io, "STALL_S", 0.05)
    data = np.random.default_rng(9).integers(0, 256, 12 * 4 * ALIGN + 99, dtype=np.uint8).tobytes()
    real_pwrite, direct_calls = os.pwrite, []

    def slow(fd, buf, off):
        if threading.current_thread().name.startswith("direct-write"):
            direct_calls.append(off)
            if len(direct_calls) == 1:
                time.sleep(0.5)                          # the disk holds the first block
        return real_pwrite(fd, buf, off)

    monkeypatch.setattr(direct_io.os, "pwrite", slow)
    f = DirectWriteFile(tmp_path / "stall.bin", block=4 * ALIGN)
    for piece in _pieces(data, np.random.default_rng(10)):
        f.write(piece)
    assert f._stalled and not f.uncached                 # went buffered while the first block was held
    f.close()
    assert len(direct_calls) <= 2                        # the held block and at most the one queued behind it
    assert (tmp_path / "stall.bin").read_bytes() == data


def test_a_series_file_written_direct_is_the_file_arrow_writes(tmp_path, monkeypatch):
    """SeriesWriter's output is byte for byte the file pyarrow writes to a path with the same settings, and a
    failed direct write (disk full) fails the write and leaves no file behind."""
    from stridelab.warehouse import store
    monkeypatch.setattr(direct_io, "WRITE_BLOCK", 16 * ALIGN)
    rng = np.random.default_rng(8)
    n = 200_000
    tab = pa.table({"t_ns": np.arange(n, dtype=np.int64) * 10_000_000, "acc_x": rng.normal(size=n),
                    "acc_y": rng.normal(size=n)})
    w = store.SeriesWriter(tmp_path, "series/a.parquet", tab.schema)
    for i in range(0, n, 30_000):
        w.write(tab.slice(i, 30_000))
    w.commit()
    if not _direct_refused(tmp_path):
        assert w._sink.direct
    ref = pq.ParquetWriter(tmp_path / "ref.parquet", tab.schema, compression={"t_ns": "zstd", "acc_x": "lz4",
                           "acc_y": "lz4"}, compression_level=1, use_dictionary=False,
                           column_encoding={"t_ns": "DELTA_BINARY_PACKED"}, write_statistics=["t_ns"],
                               write_page_checksum=True)         # every series page carries a CRC (#47)
    for i in range(0, n, 30_000):
        ref.write_table(tab.slice(i, 30_000), row_group_size=1 << 20)
    ref.close()
    assert (tmp_path / "series/a.parquet").read_bytes() == (tmp_path / "ref.parquet").read_bytes()

    if _direct_refused(tmp_path):
        return
    real_pwrite = os.pwrite

    def full(fd, buf, off):
        if off > 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_pwrite(fd, buf, off)

    monkeypatch.setattr(direct_io.os, "pwrite", full)
    w = store.SeriesWriter(tmp_path, "series/full.parquet", tab.schema)
    with pytest.raises(OSError, match="No space left"):
        for i in range(0, n, 30_000):
            w.write(tab.slice(i, 30_000))
        w.commit()
    w.abort()
    assert not (tmp_path / "series/full.parquet").exists()
    assert not [p for p in (tmp_path / "series").iterdir() if p.name.startswith(store.TMP_PREFIX)]
