"""MkDocs hook: the API pages document ``stridelab.<layer>`` modules from a tree laid out as installed.

mkdocstrings reads the sources with griffe, which finds a package by its folder, not through the import system:
``stridelab.estimators`` would have to be ``stridelab/estimators/``. In the repository the layers' folders stand
beside ``stridelab/`` (setup.py maps them, docs/architecture.md "One installed name"), so this hook links the
installed shape into a temporary folder (``stridelab/`` with its own files and one link per layer) and points the
Python handler there; the links go to the sources themselves, nothing is copied."""
from __future__ import annotations

import ast
import shutil
import tempfile
from pathlib import Path

from mkdocs.plugins import event_priority

ROOT = Path(__file__).resolve().parents[2]
_TREE: list[Path] = []


def layers() -> tuple[str, ...]:
    """The ``LAYERS`` tuple of setup.py (its one definition)."""
    for node in ast.parse((ROOT / "setup.py").read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "LAYERS" for t in node.targets):
            return tuple(ast.literal_eval(node.value))
    raise RuntimeError("setup.py defines no LAYERS")


@event_priority(100)             # before mkdocstrings reads its handler options
def on_config(config):
    tmp = Path(tempfile.mkdtemp(prefix="stridelab-docs-"))
    _TREE.append(tmp)
    pkg = tmp / "stridelab"
    pkg.mkdir()
    for p in (ROOT / "stridelab").iterdir():
        if p.name != "__pycache__":
            (pkg / p.name).symlink_to(p)
    for layer in layers():
        (pkg / layer).symlink_to(ROOT / layer, target_is_directory=True)
    config["plugins"]["mkdocstrings"].config["handlers"]["python"]["paths"] = [str(tmp)]
    return config


def on_shutdown():
    while _TREE:
        shutil.rmtree(_TREE.pop(), ignore_errors=True)
