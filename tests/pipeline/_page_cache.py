"""Helpers for the tests of reads past the page cache (test_direct_read.py, test_direct_io.py)."""
from __future__ import annotations

import os
from pathlib import Path


def uncache(p: Path) -> None:
    """Write ``p`` back to the disk and drop it from the page cache."""
    fd = os.open(p, os.O_RDONLY)
    try:
        os.fsync(fd)
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    finally:
        os.close(fd)
