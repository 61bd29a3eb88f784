"""Shared by the examples: where the data and the StrideLab home are, where figures go.

* ``STRIDELAB_HOME``: a home made by ``make demo ARGS=--no-serve`` (default ``./stridelab-home``);
* ``STRIDELAB_DATA``: the public data sets (default ``../shared/data`` beside the repository);
* ``STRIDELAB_EXAMPLES_OUT``: where figures are saved (default ``examples/output``).

An example whose data are missing exits with code 77 and says what to run (the tests then skip it).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")                       # figures go to files; no display needed

ROOT = Path(__file__).resolve().parents[1]
SKIP = 77


def out(name: str) -> Path:
    """Path of the figure ``name`` (the folder is created)."""
    d = Path(os.environ.get("STRIDELAB_EXAMPLES_OUT", ROOT / "examples" / "output"))
    d.mkdir(parents=True, exist_ok=True)
    return d / name


def data(name: str) -> Path:
    """A public data set's folder, or exit 77 naming what is missing."""
    d = Path(os.environ.get("STRIDELAB_DATA", ROOT.parent / "shared" / "data")) / name
    if not d.is_dir():
        sys.exit(_skip(f"public data set '{name}' not found at {d}; set STRIDELAB_DATA to the folder holding it"))
    return d


def home() -> Path:
    """A StrideLab home with a warehouse, or exit 77 saying how to make one."""
    h = Path(os.environ.get("STRIDELAB_HOME", ROOT / "stridelab-home"))
    if not (h / "warehouse" / "snapshots").is_dir():
        sys.exit(_skip(f"no StrideLab warehouse in {h}; run `make demo ARGS=--no-serve` first "
                       f"(or set STRIDELAB_HOME)"))
    return h


def _skip(msg: str) -> int:
    print(f"skip: {msg}", file=sys.stderr)
    return SKIP


def saved(path: Path) -> None:
    print(f"saved {path}")
