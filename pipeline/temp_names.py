"""The temporary name a file (or folder) is written under beside its final path before an atomic rename, for every
writer of the pipeline (MCAP recordings, exported tables, BIDS datasets, C3D imports)."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

#: longest file name most file systems take (ext4, xfs, btrfs: 255 bytes)
NAME_MAX = 255


def temporary_name(path: Path) -> Path:
    """``.NAME.tmp-PID`` beside ``path``, or, when that would pass :data:`NAME_MAX` bytes (an output name of more than
    ~240 bytes), ``.HASH.tmp-PID`` with a hash of the name (issue #47: such names failed with 'File name too
    long')."""
    path = Path(path)
    name = f".{path.name}.tmp-{os.getpid()}"
    if len(os.fsencode(name)) > NAME_MAX:
        name = f".{hashlib.sha256(os.fsencode(path.name)).hexdigest()[:32]}.tmp-{os.getpid()}"
    return path.with_name(name)
