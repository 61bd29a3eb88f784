"""Reads and writes of large series files that bypass the page cache (writes: :class:`DirectWriteFile`, below).

Reads, when the file is not cached already.

Why: a committed series file of :data:`stridelab.warehouse.store.UNCACHE_BYTES` or more is dropped from the page cache
once it is on the disk, and is read back once, by one stage (the ``activity`` stage reads the accelerometer
columns of a 24 h chest day: ~210 MB). A buffered read of it puts every byte into new page-cache pages first,
which on the reference machine (a VM that hands free memory back to its host) cost ~0.9 CPU-s per chest day
over a 20-participant night, most of it kernel time (docs/operations.md, "Page cache"). With ``O_DIRECT`` the disk writes straight into the
reader's own buffer, which Arrow then decodes without a further copy.

How: :func:`open_for_read` gives pyarrow a path (buffered, as before) when the file is small, mostly cached,
or the platform has no ``O_DIRECT``; otherwise a :class:`DirectFile`, a read-only file object whose reads are
widened to whole aligned blocks, read with one ``preadv`` each into a fresh aligned buffer, and returned as a
view of the requested bytes (Arrow keeps the buffer alive for as long as it uses it). Where the file system
refuses ``O_DIRECT`` (``open`` fails, or ``EINVAL`` at a read: some network and FUSE file systems) the reads go
on buffered. The cached-fraction test is :func:`cached_fraction` (``mincore(2)``).
"""
from __future__ import annotations

import ctypes
import errno
import io
import mmap
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

#: O_DIRECT offsets, lengths and buffer addresses are multiples of this (any logical block size up to 4 KiB)
ALIGN = 4096
#: read with O_DIRECT when less than this fraction of the file is in the page cache (a file is either just
#: copied or written, ~100 % cached, or dropped or long evicted, ~0 %: any value between serves; half is the
#: neutral choice). Also the inbox reader's threshold (pipeline/formats/direct_read.py)
CACHED_FRACTION = 0.5
_LIBC = []


def _libc():
    if not _LIBC:
        try:
            lib = ctypes.CDLL(None, use_errno=True)
            lib.mincore.restype = ctypes.c_int
            lib.mincore.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
        except (OSError, AttributeError):                   # pragma: no cover - no libc or no mincore
            lib = None
        _LIBC.append(lib)
    return _LIBC[0]


def cached_fraction(fd: int, size: int) -> float | None:
    """Fraction of a file's pages that are in the page cache, None where that cannot be asked.

    ``mincore(2)`` (the C library's documented call) over a read-only shared mapping of the file: for a file
    mapping it reports the pages the page cache holds, and mapping the file reads nothing (no page is touched).
    Was ``cachestat(2)`` by its raw system call number (Linux 6.5+, no C library wrapper): the same answer, 1.6 ms
    instead of 6 ms of CPU for a 674 MB day (docs/operations.md "Speed tricks: measured")."""
    if size <= 0:
        return None
    libc = _libc()
    if libc is None:
        return None
    try:
        mm = mmap.mmap(fd, size, mmap.MAP_SHARED, mmap.PROT_READ)
    except (OSError, ValueError, OverflowError):
        return None
    try:
        view = np.frombuffer(mm, np.uint8)                  # (read-only: only its address is used)
        try:
            vec = np.zeros((size + mmap.PAGESIZE - 1) // mmap.PAGESIZE, np.uint8)
            if libc.mincore(ctypes.c_void_p(view.ctypes.data), size, ctypes.c_void_p(vec.ctypes.data)) != 0:
                return None
            return min(1.0, int(np.count_nonzero(vec & 1)) * mmap.PAGESIZE / size)
        finally:
            del view
    finally:
        mm.close()


def aligned_buffer(n: int) -> np.ndarray:
    """``n`` writable bytes at an address that is a multiple of :data:`ALIGN`."""
    raw = np.empty(n + ALIGN, np.uint8)
    a = (-raw.ctypes.data) % ALIGN
    return raw[a:a + n]


class DirectFile(io.RawIOBase):
    """A read-only, seekable file object over an ``O_DIRECT`` descriptor (see the module docstring).

    ``read(n)`` returns a read-only ``memoryview`` of the bytes at the current position (fewer only at the end
    of the file); ``direct`` is False once the reads went buffered."""

    def __init__(self, path: str | os.PathLike, fd: int):
        super().__init__()
        self.name = str(path)
        self._fd = fd
        self._size = os.fstat(fd).st_size
        self._pos = 0
        self.direct = True

    # ---- io.RawIOBase -----------------------------------------------------------------------------
    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self._pos

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._pos, io.SEEK_END: self._size}[whence]
        self._pos = max(0, base + int(offset))
        return self._pos

    def size(self) -> int:                  # pyarrow.PythonFile asks for it
        return self._size

    def read(self, n: int = -1) -> memoryview:
        if n is None or n < 0:
            n = self._size - self._pos
        n = max(0, min(n, self._size - self._pos))
        out = self._pread(self._pos, n)
        self._pos += len(out)
        return out

    def readinto(self, b) -> int:
        v = self.read(len(memoryview(b)))
        memoryview(b).cast("B")[:len(v)] = v
        return len(v)

    def close(self) -> None:
        if not self.closed:
            os.close(self._fd)
        super().close()

    # ---- the read itself ----------------------------------------------------------------------------
    def _pread(self, off: int, n: int) -> memoryview:
        if n == 0:
            return memoryview(b"")
        if self.direct:
            lo = off - off % ALIGN
            hi = -(-(off + n) // ALIGN) * ALIGN
            buf = aligned_buffer(hi - lo)
            try:
                got = os.preadv(self._fd, [buf], lo)
            except OSError as e:
                if e.errno != errno.EINVAL:
                    raise
                self._go_buffered()
            else:
                got = max(0, min(got - (off - lo), n))
                return memoryview(buf[off - lo:off - lo + got]).toreadonly()
        buf = np.empty(n, np.uint8)
        got = os.preadv(self._fd, [buf], off)
        return memoryview(buf[:got]).toreadonly()

    def _go_buffered(self) -> None:
        """O_DIRECT refused at read time: reopen the file for buffered reads."""
        fd = os.open(self.name, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
        os.close(self._fd)
        self._fd, self.direct = fd, False


def open_for_read(path: str | os.PathLike, min_bytes: int):
    """What to hand pyarrow for reading ``path``: the path itself (buffered reads), or a :class:`DirectFile`
    when the file has at least ``min_bytes``, is mostly not in the page cache and ``O_DIRECT`` is available."""
    o_direct = getattr(os, "O_DIRECT", 0)            # not on macOS: always buffered there
    if not o_direct:
        return path
    try:
        size = os.stat(path).st_size
    except OSError:
        return path                                  # pyarrow reports the missing file
    if size < min_bytes:
        return path
    try:
        fd = os.open(path, os.O_RDONLY | o_direct | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return path                                  # no O_DIRECT on this file system: buffered
    frac = cached_fraction(fd, size)
    if frac is not None and frac >= CACHED_FRACTION:
        os.close(fd)
        return path
    return DirectFile(path, fd)


#: bytes per O_DIRECT write of a series file (a multiple of :data:`ALIGN`); a file that never fills one block
#: is written buffered, as before
WRITE_BLOCK = 4 << 20
#: seconds the writer waits for the disk to take a block before it writes the rest of the file buffered
STALL_S = 1.0


class DirectWriteFile(io.RawIOBase):
    """A write-only, sequential file object that bypasses the page cache once the file grows past one block.

    Why: a buffered write of a large series file (a 24 h chest day: ~420 MB) puts every byte into new
    page-cache pages before the disk sees it, and on the reference machine (a VM whose free memory goes back
    to its host) each new page costs kernel time: ``dd`` of 416 MB took 0.58-1.19 CPU-s of system time
    buffered and 0.06-0.09 s with ``O_DIRECT``, measured here. The file is dropped from the page cache after its
    ``fsync`` anyway (:meth:`stridelab.warehouse.store.SeriesWriter.commit`) and read back once, with ``O_DIRECT``.

    How: writes collect in an aligned buffer of :data:`WRITE_BLOCK` bytes, allocated once the file reaches that
    size (a small file is kept as the pieces written and written with one buffered ``write`` at :meth:`close`, as
    before). The first full block opens an ``O_DIRECT`` descriptor; each full block is handed to one writer thread
    (``pwrite``) while the other one fills (two blocks in all: the disk takes a block in a few milliseconds, the
    encoder fills it in ~30). :meth:`close` writes the tail padded to :data:`ALIGN` and truncates the file to its
    length. Where ``O_DIRECT`` is refused (``open`` fails, or ``EINVAL`` at a write) the blocks go on buffered, and
    so do they once the disk has not taken a block for :data:`STALL_S` (a buffered write lets the page cache absorb
    a stall of a shared disk; a direct one would hold up the encoder for as long). The bytes of the file are the
    same either way; durability is the caller's ``fsync``, as with any file.
    ``direct`` tells whether any block went to the disk directly."""

    def __init__(self, path: str | os.PathLike, block: int | None = None):
        super().__init__()
        block = WRITE_BLOCK if block is None else block
        if block <= 0 or block % ALIGN:
            raise ValueError(f"block must be a positive multiple of {ALIGN}")
        self.name = str(path)
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0), 0o644)
        self._dfd: int | None = None
        self._block = block
        self._small: list[bytes] = []       # a file's first bytes, until they fill a block
        self._small_n = 0
        self._free: list = []
        self._cur = None                    # the block being filled (aligned), once there is one
        self._fill = 0                      # bytes in self._cur
        self._off = 0                       # file offset of self._cur[0]
        self._pool = None
        self._inflight: list = []
        self._tried = False
        self._stalled = False
        self.direct = False

    def writable(self) -> bool:
        return True

    @property
    def uncached(self) -> bool:
        """True while full blocks go to the disk past the page cache (an ``O_DIRECT`` descriptor is open and the
        disk keeps up)."""
        return self._dfd is not None and not self._stalled

    def tell(self) -> int:
        return self._off + self._fill + self._small_n

    def write(self, b) -> int:
        src = memoryview(b).cast("B")
        n = len(src)
        if self._cur is None:
            if self._small_n + n < self._block:       # a small file never allocates a block
                self._small.append(b if isinstance(b, bytes) else bytes(src))
                self._small_n += n
                return n
            self._free = [aligned_buffer(self._block) for _ in range(2)]
            self._cur = self._free.pop()
            head, self._small, self._small_n = self._small, [], 0
            for piece in head:
                self._cur[self._fill:self._fill + len(piece)] = np.frombuffer(piece, np.uint8)
                self._fill += len(piece)
        done = 0
        while done < n:
            take = min(n - done, self._block - self._fill)
            memoryview(self._cur)[self._fill:self._fill + take] = src[done:done + take]
            self._fill += take
            done += take
            if self._fill == self._block:
                self._put_block()
        return n

    def _put_block(self) -> None:
        """Hand the full current block to the disk and start filling a free one."""
        if not self._tried:
            self._tried = True
            o_direct = getattr(os, "O_DIRECT", 0)
            if o_direct:
                try:
                    self._dfd = os.open(self.name, os.O_WRONLY | o_direct | getattr(os, "O_CLOEXEC", 0))
                except OSError:
                    self._dfd = None                 # no O_DIRECT on this file system: buffered
            if self._dfd is not None:
                self._pool = ThreadPoolExecutor(1, thread_name_prefix="direct-write")
        buf, off = self._cur, self._off
        if self._pool is None or self._stalled:
            self._pwrite_buffered(buf, self._block, off)        # no O_DIRECT descriptor, or the disk lagged
        else:
            while not self._free:
                fut, oldest = self._inflight[0]
                try:
                    fut.result(timeout=STALL_S)
                except TimeoutError:
                    # the disk has not taken a block for STALL_S: the rest of the file goes through the page
                    # cache, which absorbs a stall as it did before; the block in flight lands when it lands
                    self._stalled = True
                    break
                self._inflight.pop(0)
                self._free.append(oldest)
            if self._stalled:
                self._pwrite_buffered(buf, self._block, off)
            else:
                self._inflight.append((self._pool.submit(self._pwrite_direct, buf, self._block, off), buf))
                self._cur = self._free.pop()
        self._off += self._block
        self._fill = 0

    def _pwrite_direct(self, buf, n: int, off: int) -> None:
        """On the writer thread: ``n`` bytes of ``buf`` (aligned) at ``off``, directly if still possible."""
        if self._dfd is not None:
            try:
                written = os.pwrite(self._dfd, buf[:n], off)
            except OSError as e:
                if e.errno != errno.EINVAL:
                    raise
                self._dfd_refused()
            else:
                if written == n:
                    self.direct = True
                    return
                off, buf, n = off + written, buf[written:], n - written     # a short write: the rest buffered
        self._pwrite_buffered(buf, n, off)

    def _pwrite_buffered(self, buf, n: int, off: int) -> None:
        while n:
            written = os.pwrite(self._fd, buf[:n], off)
            off, buf, n = off + written, buf[written:], n - written

    def _dfd_refused(self) -> None:
        fd, self._dfd = self._dfd, None
        os.close(fd)

    def _wait_oldest(self):
        fut, buf = self._inflight.pop(0)
        fut.result()
        return buf

    def close(self) -> None:
        if self.closed:
            return
        try:
            while self._inflight:
                self._free.append(self._wait_oldest())
            if self._small:
                data = b"".join(self._small)
                self._small, self._small_n = [], 0
                self._pwrite_buffered(memoryview(data), len(data), 0)   # never reached a block: no O_DIRECT
            n = self._fill
            if n:
                if self._dfd is not None and not self._stalled:
                    padded = -(-n // ALIGN) * ALIGN
                    self._cur[n:padded] = 0
                    self._pwrite_direct(self._cur, padded, self._off)
                    os.ftruncate(self._fd, self._off + n)
                else:
                    self._pwrite_buffered(self._cur, n, self._off)
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)          # a failed write's siblings finish first
                self._pool = None
            if self._dfd is not None:
                os.close(self._dfd)
                self._dfd = None
            os.close(self._fd)
            super().close()
