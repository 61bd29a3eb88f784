"""Immutable Parquet store for bulk time series.

Files live under ``<root>/series/study=…/participant=…/session=…/placement=…/`` and are written
to a temporary name and renamed into place, so a reader (or a crash) never sees half a file. A
file is never modified after the rename; a recomputation writes a new file (its name carries the
content stamp) and the old one is garbage-collected once no catalog or snapshot refers to it.
"""
from __future__ import annotations

import os
import re
import uuid
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from stridelab.warehouse.direct_io import DirectWriteFile

_SAFE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,127}")     # whole string (fullmatch: '$' would pass 'P001\n')
TMP_PREFIX = ".tmp-"
#: uncompressed bytes handed to a series file between two background flushes to the disk (fdatasync)
WRITEBACK_BYTES = 64 << 20
#: a committed series file at least this large leaves the page cache once it is on the disk (see commit)
UNCACHE_BYTES = 64 << 20
#: flushes of one recording's series files in flight at once (:func:`commit_all`); 28 files of 200 kB beside a
#: concurrent O_DIRECT writer, here: one at a time 105-130 ms, 8 threads 52-67 ms, 28 threads 60-63 ms
FLUSH_THREADS = 8


def check_identifier(value: str, what: str) -> str:
    """Identifiers that become path parts: letters, digits, ``. _ -``; never ``..`` or ``/``. The message
    does not repeat the value (it may be personal data)."""
    if not isinstance(value, str) or not _SAFE.fullmatch(value) or ".." in value:
        raise ValueError(f"{what} is not a safe identifier (use letters, digits, '.', '_', '-'; "
                         f"at most 128 characters)")
    return value


def series_relpath(study: str, participant: str, session: str, placement: str, name: str) -> str:
    """Relative path of a series file; every part is checked to be a safe identifier."""
    parts = [f"study={check_identifier(study, 'study')}",
             f"participant={check_identifier(participant, 'participant')}",
             f"session={check_identifier(session, 'session')}",
             f"placement={check_identifier(placement, 'placement')}",
             f"{check_identifier(name, 'series name')}.parquet"]
    return "series/" + "/".join(parts)


class SeriesWriter:
    """Stream record batches into a Parquet file that appears atomically on :meth:`commit`.

    Writes run on a background thread (Arrow releases the GIL while encoding and compressing), so
    the caller decodes the next block meanwhile; at most two blocks are in flight. The encoded bytes go to the
    disk through :class:`stridelab.warehouse.direct_io.DirectWriteFile` (past the page cache once the file outgrows a
    block of 4 MiB).
    """

    def __init__(self, root: Path, relpath: str, schema: pa.Schema):
        self.root = Path(root)
        self.relpath = relpath
        self.final = self.root / relpath
        self.final.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = self.final.with_name(f"{TMP_PREFIX}{uuid.uuid4().hex}-{self.final.name}")
        # no dictionary encoding for numeric columns: sensor values almost never repeat, so Arrow builds a
        # dictionary, overflows it and falls back to plain, at 3x the CPU of writing plain (ingest profile)
        dict_cols = [f.name for f in schema if not (pa.types.is_integer(f.type) or pa.types.is_floating(f.type))]
        # floating-point sensor columns: LZ4. Real devices' values are scaled integer counts: LZ4 stores the UCI
        # chest set's acc in 36 % and BROAD's acc + gyr in 53 % of the plain size (zstd-1: 17 %, 34 %, for ~1.7x
        # the CPU of the whole slice write, 0.141 vs 0.093 CPU-s per 2^19 IMU rows). The simulator's noise-like
        # mantissas do not compress (LZ4 +0.4 %, 0.25 CPU-s per 24 h write): left as they are, tuned on real data.
        # Everything else zstd-1.
        comp = {f.name: "lz4" if pa.types.is_floating(f.type) else "zstd" for f in schema}
        # 32/64-bit integer columns (time stamps above all) DELTA_BINARY_PACKED: a regular clock packs to a
        # few bits per row; a 24 h 100 Hz IMU series wrote in 1.17 instead of 1.40 CPU-s, 417 instead of 513 MB
        delta = {f.name: "DELTA_BINARY_PACKED" for f in schema
                 if pa.types.is_integer(f.type) and f.type.bit_width in (32, 64)}
        # the bytes go to the disk past the page cache once the file outgrows one block (warehouse/direct_io.py).
        # Arrow hands over each page and page header (~6,300 Python calls per 24 h IMU series, ~20 ms); an Arrow
        # buffer in between would cost a third copy of every byte (7-day ingest: ~1 CPU-s more user time)
        self._sink = DirectWriteFile(self.tmp)
        try:
            self._out = pa.PythonFile(self._sink, mode="w")
            self._w = pq.ParquetWriter(self._out, schema, compression=comp, compression_level=1,
                                       use_dictionary=dict_cols or False, column_encoding=delta or None,
                                       write_statistics=["t_ns"] if "t_ns" in schema.names else True,
                                       # a CRC-32 per page, verified by every read (:func:`open_series`): a flipped
                                       # bit on the disk is reported, never served (docs/integrity.md)
                                       write_page_checksum=True)
        except BaseException:
            self._sink.close()
            self.tmp.unlink(missing_ok=True)
            raise
        self.n_rows = 0
        self._pool: ThreadPoolExecutor | None = None
        self._pending: list[Future] = []
        self._unsynced = 0
        self._sync_fd: int | None = None
        self._sync_pool: ThreadPoolExecutor | None = None
        self._sync: Future | None = None

    def write(self, table: pa.Table, last: bool = False) -> None:
        """Encode ``table`` on the writer thread; ``last=True`` for a file's only table writes it here (no thread
        for a small series)."""
        if last and self._pool is None:
            self._write(table)
            self.n_rows += table.num_rows
            return
        while len(self._pending) >= 2:
            self._pending.pop(0).result()
        if self._pool is None:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="parquet")
        self._pending.append(self._pool.submit(self._write, table))
        self.n_rows += table.num_rows

    def _write(self, table: pa.Table) -> None:
        """On the writer thread: encode the table. Where the file is written buffered (small so far, or no
        ``O_DIRECT``): once ``WRITEBACK_BYTES`` have accumulated, start pushing what was written so far to the disk
        on a third thread (never waiting for it here). The final ``fsync``
        of :meth:`commit` then only waits for the tail: a 24 h IMU series (~420 MB) spent ~0.8 s of wall time
        in that one ``fsync`` at the end of an ingest, with both cores idle."""
        self._w.write_table(table, row_group_size=1 << 20)
        self._unsynced += table.nbytes
        if self._sink.uncached:
            return                                    # nothing waits in the page cache
        if self._unsynced >= WRITEBACK_BYTES and (self._sync is None or self._sync.done()):
            if self._sync is not None:
                self._sync.result()                   # a failed flush (EIO, ENOSPC) fails the write
            if self._sync_fd is None:
                self._sync_fd = os.open(self.tmp, os.O_RDONLY)
                self._sync_pool = ThreadPoolExecutor(1, thread_name_prefix="parquet-sync")
            self._sync = self._sync_pool.submit(os.fdatasync, self._sync_fd)
            self._unsynced = 0

    def _drain(self) -> None:
        try:
            for f in self._pending:
                f.result()
        finally:
            self._pending = []
            if self._pool is not None:
                self._pool.shutdown(wait=True)
            if self._sync_pool is not None:
                self._sync_pool.shutdown(wait=True)       # a flush in progress finishes first
                os.close(self._sync_fd)
                last, self._sync_fd, self._sync_pool, self._sync = self._sync, None, None, None
                if last is not None:
                    last.result()

    def commit(self, relpath: str | None = None) -> str:
        """Close and move into place, at ``relpath`` if given (e.g. a name known only at the end).

        A file of at least :data:`UNCACHE_BYTES` is dropped from the page cache once it is on the disk
        (``POSIX_FADV_DONTNEED``): a night writes ~420 MB per 24 h chest day, read back once by one stage, and
        keeping it cached grows the page cache by the whole night's output, each page new memory. Dropped, its
        pages are reused by the next file's writes (on the reference VM, whose free memory goes back to the
        host, a new page costs ~2-3 CPU-s per GB). With the uncached reads of pipeline/formats/direct_read.py the
        20-participant night went from 116 to 103 s (docs/operations.md, "Page cache"). The one later read comes
        from the disk."""
        self._close(relpath)
        self._flush()
        return self._place()

    def _close(self, relpath: str | None) -> None:
        self._drain()
        self._w.close()
        self._out.close()
        if relpath is not None:
            self.relpath, self.final = relpath, self.root / relpath
            self.final.parent.mkdir(parents=True, exist_ok=True)

    def _flush(self) -> None:
        with open(self.tmp, "rb") as f:
            os.fsync(f.fileno())
            if hasattr(os, "posix_fadvise") and os.fstat(f.fileno()).st_size >= UNCACHE_BYTES:
                os.posix_fadvise(f.fileno(), 0, 0, os.POSIX_FADV_DONTNEED)

    def _place(self) -> str:
        os.replace(self.tmp, self.final)
        return self.relpath

    def abort(self) -> None:
        """Discard the file. Errors of writes still in flight are not raised again: the file is given up
        (the caller is usually handling the first of them already)."""
        try:
            try:
                self._drain()
            except Exception:  # noqa: BLE001 - see docstring
                pass
            finally:
                try:
                    self._w.close()
                finally:
                    try:
                        self._out.close()
                    except Exception:  # noqa: BLE001 - see docstring
                        pass
                    finally:
                        self._sink.close()
        finally:
            self.tmp.unlink(missing_ok=True)


def commit_all(writers: list[SeriesWriter], relpaths: list[str | None]) -> list[str]:
    """:meth:`SeriesWriter.commit` for the series files of one recording, their flushes to the disk side by side.

    A lab recording holds ~28 series (IMU, magnetometer, reference pose and range of 8 placements), each a small
    file. One ``fsync`` after the other, each waited for its own journal commit: ~0.07 s of idle worker per lab
    recording in a 20-participant night, while the other worker streamed a 24 h day to the disk (4.4 s of the
    night's worker time). Flushed together, the file system takes them into shared journal commits. All files
    are closed first and moved into place only after every flush succeeded; an error is raised as by
    ``commit`` (the caller aborts the writers, as after a failed ``commit``)."""
    for w, rel in zip(writers, relpaths, strict=True):
        w._close(rel)
    if len(writers) > 1:
        with ThreadPoolExecutor(min(FLUSH_THREADS, len(writers)), thread_name_prefix="series-flush") as ex:
            for f in [ex.submit(w._flush) for w in writers]:
                f.result()
    elif writers:
        writers[0]._flush()
    return [w._place() for w in writers]


def write_table(root: Path, relpath: str, table: pa.Table) -> str:
    """Write a whole table atomically; returns ``relpath``."""
    w = SeriesWriter(root, relpath, table.schema)
    try:
        w.write(table, last=True)
    except BaseException:
        w.abort()
        raise
    return w.commit()


class SeriesDamaged(RuntimeError):
    """A stored series file fails its checks (a page checksum, the footer, missing): it is not served.
    ``str(err)`` is one line naming the file and what to do."""

    def __init__(self, relpath: str, detail: str):
        self.relpath, self.detail = relpath, detail
        super().__init__(f"series file {relpath} is damaged ({detail}): not served; "
                         f"run `stridelab verify --repair` (docs/integrity.md)")


@contextmanager
def damage_check(relpath: str):
    """Turn what a damaged or missing series file raises while it is read into :class:`SeriesDamaged`."""
    try:
        yield
    except SeriesDamaged:
        raise
    except FileNotFoundError:
        raise SeriesDamaged(relpath, "the file is missing") from None
    except (OSError, pa.ArrowException, ValueError, UnicodeDecodeError, EOFError) as e:
        detail = str(e).splitlines()[0][:160] if str(e) else type(e).__name__
        if "CRC" in detail or "checksum" in detail:
            detail = "a page checksum does not match"
        raise SeriesDamaged(relpath, detail) from None


def open_series(root: Path, relpath: str, source=None, **kw) -> pq.ParquetFile:
    """A series file opened with page checksum verification (every page read is checked; files written before
    the checksums have none to check). ``source``: an already opened file (direct reads)."""
    with damage_check(relpath):
        return pq.ParquetFile(Path(root) / relpath if source is None else source,
                              page_checksum_verification=True, **kw)


def read_table(root: Path, relpath: str, columns: list[str] | None = None) -> pa.Table:
    """Read a series file (relative to the warehouse root), every page's checksum verified; raises
    :class:`SeriesDamaged` for a damaged or missing file."""
    with damage_check(relpath):
        return pq.read_table(Path(root) / relpath, columns=columns, page_checksum_verification=True)
