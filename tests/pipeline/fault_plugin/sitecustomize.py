"""Fault injection for tests/pipeline/test_faults.py, kept out of the package: a test puts this folder on the
``PYTHONPATH`` of the ``stridelab`` process it starts, so that process and every worker it spawns (``spawn``
start method: each is a fresh interpreter, which imports ``sitecustomize`` as it starts) load this module.

With ``STRIDELAB_TEST_KILL_WORKER_ONCE=<marker>``, the first stage task (``stridelab.pipeline.runner._stage_task``, in a
worker) that finds no marker file creates it and SIGKILLs its own process. With
``STRIDELAB_TEST_KILL_COORDINATOR_IN_COMMIT=<marker>``, the coordinator SIGKILLs itself the first time it inserts
a stage's rows, i.e. inside the stage's commit transaction, after its DELETE and before its INSERT. Production
code reads neither variable.
"""
from __future__ import annotations

import os

_WORKER = os.environ.get("STRIDELAB_TEST_KILL_WORKER_ONCE")
_COMMIT = os.environ.get("STRIDELAB_TEST_KILL_COORDINATOR_IN_COMMIT")


def _kill_once(marker: str) -> None:
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.close(fd)
    os.kill(os.getpid(), 9)


def _install() -> None:
    from stridelab.pipeline import runner
    if _WORKER:
        task = runner._stage_task

        def _stage_task(*args):
            _kill_once(_WORKER)
            return task(*args)
        # pickled by reference as stridelab.pipeline.runner._stage_task, which is this wrapper in every process
        _stage_task.__module__, _stage_task.__qualname__ = task.__module__, task.__qualname__
        runner._stage_task = _stage_task
    if _COMMIT:
        from stridelab.pipeline.stages import registry
        from stridelab.warehouse.catalog import Warehouse
        insert = Warehouse.insert

        def _insert(self, table, rows, *args, **kw):
            if table in {t for s in registry() for t in s.tables}:
                _kill_once(_COMMIT)
            return insert(self, table, rows, *args, **kw)
        Warehouse.insert = _insert


if _WORKER or _COMMIT:
    _install()
