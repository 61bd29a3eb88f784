"""Worker processes that die with their coordinator.

When the coordinator (the process holding the run lock) is killed, by the out-of-memory killer or
``kill -9``, nothing tells its pool workers: they finish their task, wait for the next one and,
about 600 MB each, hold the caller's pipes open for minutes. :func:`die_with_parent` runs first in
every worker: on Linux it asks the kernel to SIGKILL the worker when its parent dies
(``prctl(PR_SET_PDEATHSIG)``), and everywhere it starts a watchdog thread that kills the worker when
its parent pid changes (the kernel re-parents orphans), which also covers the gap before ``prctl``.

Used as the initializer of the local process pool and as a Dask preload (``dask_setup``) of the
LocalCluster's worker processes. Workers of a separate Dask cluster (``--scheduler``) are not the
coordinator's children and are left alone.
"""
from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

PR_SET_PDEATHSIG = 1          # <linux/prctl.h>
POLL_S = 0.5
#: the coordinator's pid, inherited by Dask worker processes: a worker whose preload runs only after
#: the coordinator died (worker start-up takes seconds) must not adopt its new parent (init)
COORDINATOR_ENV = "STRIDELAB_COORDINATOR_PID"


def _kill_self() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def die_with_parent(parent_pid: int | None = None, poll_s: float = POLL_S) -> None:
    """Make this process die when ``parent_pid`` (default: the current parent) exits."""
    parent = parent_pid if parent_pid is not None else os.getppid()
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):     # pragma: no cover - no libc prctl: the watchdog remains
            pass
    if os.getppid() != parent:                # the parent died before prctl took effect
        _kill_self()

    def watch() -> None:
        while True:
            if os.getppid() != parent:
                _kill_self()
            time.sleep(poll_s)

    threading.Thread(target=watch, name="stridelab-lifeline", daemon=True).start()


def dask_setup(worker=None) -> None:
    """Dask preload hook (``preload=["stridelab.pipeline.lifeline"]``): runs in each worker process at start."""
    pid = os.environ.get(COORDINATOR_ENV)
    die_with_parent(int(pid) if pid and pid.isdigit() else None)
