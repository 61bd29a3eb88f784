"""The run lock: one writing process per warehouse (DuckDB allows one writer)."""
from __future__ import annotations

import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path


class WarehouseBusy(RuntimeError):
    """Another process holds the warehouse lock; ``str(err)`` says who and what to do."""


class RunLock:
    """Exclusive, non-blocking ``flock`` on ``<root>/.lock``; released by the kernel if the process dies."""

    def __init__(self, root: Path, command: str = " ".join(sys.argv)):
        self.path = Path(root) / ".lock"
        self.command = command
        self._fd: int | None = None

    def __enter__(self) -> "RunLock":
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                info = json.loads(os.pread(fd, 4096, 0) or b"{}")
            except ValueError:
                info = {}
            os.close(fd)
            since = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(info.get("since", 0))) if info else "?"
            raise WarehouseBusy(
                f"another stridelab process (pid {info.get('pid', '?')} on {info.get('host', '?')}, "
                f"'{info.get('command', '?')}', since {since}) is writing to {self.path.parent}; "
                f"wait for it to finish (a reader such as the dashboard never needs this lock)") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "command": self.command,
                                  "since": time.time()}).encode(), 0)
        self._fd = fd
        return self

    def __exit__(self, *exc) -> None:
        if self._fd is not None:
            os.ftruncate(self._fd, 0)
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None
