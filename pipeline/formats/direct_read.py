"""Sequential reads of a large recording that bypass the page cache when the file is not cached already.

Why: an inbox file is read once (decoded and hashed on the same pass), so caching it buys nothing. On the
reference machine (a VM that hands free memory back to its host) a buffered read of a cold file also costs
~2 CPU-s per GB in the kernel: each new page-cache page is memory the host must back and zero again before
the copy to the reader can run (``perf`` over a 20-participant night: ``_copy_to_iter`` under ``read`` was
10 % of all CPU). With ``O_DIRECT`` the disk writes straight into the reader's own (reused) buffers:
0.02-0.03 instead of 1.2-1.5 CPU-s per 674 MB chest day, 0.45 s of disk time (docs/operations.md, "Page
cache").

How: :class:`SequentialReader` asks the kernel which fraction of the file is in the page cache (``mincore`` over
a mapping of the file; :func:`stridelab.warehouse.direct_io.cached_fraction`, shared with the warehouse's reads of series files).
A file mostly cached (just copied into the inbox, just written by a bench) is read buffered, as before;
otherwise an ``O_DIRECT`` descriptor is read in aligned blocks by one read-ahead thread, up to two blocks
ahead of the consumer, so the disk works while the decoder does. Files under two blocks are always
read buffered. Where ``O_DIRECT`` is refused (``open`` fails, or ``EINVAL`` on the first read: some network
and FUSE file systems) the reader goes on buffered from the same position. A file truncated while it is read
gives a short read, exactly as a buffered read does (never a ``SIGBUS``, as a memory map would), so the
caller's "truncated MCAP" check still holds.
"""
from __future__ import annotations

import errno
import mmap
import os
import queue
import threading

from stridelab.warehouse.direct_io import CACHED_FRACTION, cached_fraction

#: bytes per O_DIRECT read (a multiple of any block size); two such blocks are in flight
BLOCK = 8 << 20


class SequentialReader:
    """``readinto`` / ``tell`` over a file read front to back (see the module docstring).

    ``direct`` tells which path was taken (False: buffered). Close it (or use it as a context manager)."""

    def __init__(self, path: str | os.PathLike, size: int, force: bool | None = None):
        self.size = size
        self.pos = 0
        self._f = open(path, "rb", buffering=0)
        self.direct = False
        self._thread: threading.Thread | None = None
        want = force
        if want is None:
            frac = cached_fraction(self._f.fileno(), size)
            want = frac is None or frac < CACHED_FRACTION
        o_direct = getattr(os, "O_DIRECT", 0)             # not on macOS: always buffered there
        if want and o_direct and size >= 2 * BLOCK:
            try:
                self._fd = os.open(path, os.O_RDONLY | o_direct | getattr(os, "O_CLOEXEC", 0))
            except OSError:
                return                                      # no O_DIRECT here: buffered
            self.direct = True
            self._free: queue.Queue = queue.Queue()
            for _ in range(3):
                self._free.put(mmap.mmap(-1, BLOCK))
            self._full: queue.Queue = queue.Queue()
            self._stop = threading.Event()
            self._cur: tuple[mmap.mmap, int, int] | None = None     # (buffer, bytes in it, consumed)
            self._eof = False
            self._thread = threading.Thread(target=self._ahead, name="direct-read", daemon=True)
            self._thread.start()

    # ---- read-ahead thread ----------------------------------------------------------------------
    def _ahead(self) -> None:
        off = 0
        try:
            while not self._stop.is_set():
                buf = self._free.get()
                if buf is None:
                    return
                n = os.preadv(self._fd, [buf], off)
                self._full.put((buf, n, None))
                off += n
                if n < BLOCK:
                    return                                  # end of file (or truncated meanwhile)
        except OSError as e:
            self._full.put((None, 0, e))

    # ---- consumer -------------------------------------------------------------------------------
    def readinto(self, dst) -> int:
        """Fill ``dst`` (a writable buffer) from the current position; fewer bytes only at the end of the file."""
        if not self.direct:
            n = self._f.readinto(dst) or 0
            self.pos += n
            return n
        dst = memoryview(dst).cast("B")
        done = 0
        while done < len(dst):
            if self._cur is None:
                if self._eof:
                    break
                buf, n, err = self._full.get()
                if err is not None:
                    if err.errno != errno.EINVAL:
                        raise err
                    self.pos += done                        # O_DIRECT refused at read time: go on buffered
                    self._fallback()
                    return done + self.readinto(dst[done:])
                self._cur = (buf, n, 0)
                self._eof = n < BLOCK                       # a short block is the last one
            buf, n, used = self._cur
            take = min(n - used, len(dst) - done)
            dst[done:done + take] = memoryview(buf)[used:used + take]
            done += take
            if used + take == n:
                self._cur = None
                self._free.put(buf)
            else:
                self._cur = (buf, n, used + take)
        self.pos += done
        return done

    def _fallback(self) -> None:
        """Continue buffered from the current position (the read-ahead thread has stopped)."""
        self._stop_thread()
        self.direct = False
        self._f.seek(self.pos)

    def read(self) -> bytes:
        """The rest of the file (buffered: whatever is there now; direct: up to the size given)."""
        if not self.direct:
            out = self._f.read() or b""
            self.pos += len(out)
            return out
        out = bytearray(max(0, self.size - self.pos))
        return bytes(out[:self.readinto(out)])

    def tell(self) -> int:
        return self.pos

    def _stop_thread(self) -> None:
        if self._thread is not None:
            self._stop.set()
            self._free.put(None)
            self._thread.join()
            self._thread = None
            os.close(self._fd)

    def close(self) -> None:
        if self.direct:
            self._stop_thread()
        self._f.close()

    def __enter__(self) -> "SequentialReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
