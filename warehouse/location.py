"""Where the warehouse lives by default: ``$STRIDELAB_HOME/warehouse`` (``STRIDELAB_HOME`` defaults to
``./stridelab-home``). One definition for every layer: the pipeline writes there, the dashboard and the reports read
there (``stridelab.pipeline.config`` re-exports these for the other folders under the home)."""
from __future__ import annotations

import os
from pathlib import Path


def home() -> Path:
    return Path(os.environ.get("STRIDELAB_HOME", "stridelab-home")).resolve()


def default_warehouse() -> Path:
    return home() / "warehouse"
