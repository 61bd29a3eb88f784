"""validation/provenance.toml lists every tuned constant; each entry must match the code (issue 16, point 2).

A constant named there that changes without its entry being updated fails here, as does an entry whose
path no longer resolves or that lacks the data / procedure / figure it was chosen with.
"""
from __future__ import annotations

import importlib
import json
import math
import tomllib
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parent.parent
PROVENANCE = PROJECT_ROOT / "validation" / "provenance.toml"
FIELDS = ("path", "value", "data", "procedure", "figure")


def _entries() -> list[dict]:
    with PROVENANCE.open("rb") as f:
        return tomllib.load(f)["constant"]


def resolve(path: str):
    """The value at ``path``: "pkg.module.Name.attr" (longest importable module prefix, then attributes)
    or "relative/file.json#key.key" (a value in a JSON file of the repository)."""
    if "#" in path:
        file, _, keys = path.partition("#")
        obj = json.loads((PROJECT_ROOT / file).read_text())
        for k in keys.split("."):
            obj = obj[k]
        return obj
    parts = path.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for name in parts[cut:]:
            obj = getattr(obj, name)
        return obj
    raise ModuleNotFoundError(f"no importable module in {path!r}")


def same(a, b) -> bool:
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return (isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)) and len(a) == len(b)
                and all(same(x, y) for x, y in zip(a, b)))
    if isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str) or isinstance(b, str):
        return type(a) is type(b) and a == b
    return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=0.0)


def test_entries_are_complete_and_unique():
    entries = _entries()
    assert entries, "validation/provenance.toml lists no constant"
    for e in entries:
        missing = [k for k in FIELDS if k not in e or (isinstance(e[k], str) and not e[k].strip())]
        assert not missing, f"provenance entry {e.get('path')!r} lacks {missing}"
    paths = [e["path"] for e in entries]
    assert len(paths) == len(set(paths)), "a constant is listed twice"


@pytest.mark.parametrize("entry", _entries(), ids=lambda e: e["path"])
def test_constant_matches_its_entry(entry):
    actual = resolve(entry["path"])
    assert same(actual, entry["value"]), (
        f"{entry['path']} is {actual!r} in the code but {entry['value']!r} in validation/provenance.toml: "
        "update its entry (value, data, procedure, figure) when a tuned constant changes")


def test_same_compares_what_it_should():
    assert same(0.3, 0.3) and same((1.0, 2.0), [1.0, 2.0]) and same("direction", "direction")
    assert not same(0.3, 0.30001) and not same((1.0, 2.0), [1.0]) and not same("direction", "thesis")
    assert not same(True, 1.0)
