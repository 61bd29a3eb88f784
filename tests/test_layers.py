"""Imports flow one way (DESIGN.md "Layers", issue 16 point 8): an AST scan of every module of the project.

estimators <- warehouse <- pipeline <- reports / validation <- stridelab (the command line that wires them);
dashboard reads the warehouse (and the reports, and the scorers ``estimators.<family>.evaluation``) only;
the simulator (``stridelab.validation.simulator``) imports nothing from ``estimators`` (its ground truth is its own code).
Every ``import`` statement counts, including the lazy ones inside functions.

The folders are the layers; installed, each is imported as ``stridelab.<layer>`` (setup.py). The rules below name
the layers without that prefix (``_canon`` strips it); an import of a layer by its bare folder name is reported:
it works only from the repository root and breaks every installed copy.
"""
from __future__ import annotations

import ast
import functools
import os
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("estimators", "studies", "warehouse", "pipeline", "reports", "dashboard", "validation", "stridelab")
NAMESPACE = "stridelab"
LAYERS = tuple(p for p in PACKAGES if p != NAMESPACE)   # installed as stridelab.<layer>


def _canon(name: str) -> str:
    """``stridelab.pipeline.x`` -> ``pipeline.x`` (the name the rules use); ``stridelab.cli`` stays."""
    head, _, rest = name.partition(".")
    if head == NAMESPACE and rest.split(".")[0] in LAYERS:
        return rest
    return name


def _installed(module: str) -> str:
    """``pipeline.x`` (a file's module by its folder) -> ``stridelab.pipeline.x`` (its name once installed)."""
    return f"{NAMESPACE}.{module}" if module.split(".")[0] in LAYERS else module


def _bare(name: str) -> bool:
    """An import of a layer by its folder name (``pipeline.x``): not importable once installed."""
    return name.split(".")[0] in LAYERS


#: package (or sub-package: the longest prefix wins) -> project packages it may import
ALLOWED: dict[str, set[str]] = {
    "estimators": {"estimators"},
    "studies": {"studies"},
    "warehouse": {"warehouse", "estimators"},
    "pipeline": {"pipeline", "warehouse", "estimators", "studies"},
    "reports": {"reports", "warehouse", "estimators"},
    "dashboard": {"dashboard", "warehouse", "reports", "estimators.*.evaluation"},
    "validation": {"validation", "pipeline", "warehouse", "estimators", "studies", "reports", "dashboard"},
    "stridelab.validation.simulator": {"stridelab.validation.simulator", "studies"},
    "stridelab": set(PACKAGES),
}
#: entry points that may import upward: ``python -m stridelab.pipeline`` is kept as an alias of ``python -m stridelab``
EXCEPTIONS = {("stridelab.pipeline.__main__", "stridelab.cli")}


def _rule(module: str) -> set[str]:
    rules = {_canon(k): v for k, v in ALLOWED.items()}
    best = max((k for k in rules if module == k or module.startswith(k + ".")), key=len)
    return rules[best]


def _permitted(target: str, allowed: set[str]) -> bool:
    for a in map(_canon, allowed):
        if a == "estimators.*.evaluation":
            parts = target.split(".")
            if parts[0] == "estimators" and len(parts) == 3 and parts[2] == "evaluation":
                return True
        elif target == a or target.startswith(a + "."):
            return True
    return False


def _walk(tree, rel: Path):
    """(node, absolute module) of every import of the module at ``rel`` (relative to the project root)."""
    parts = list(rel.with_suffix("").parts)
    package = parts[:-1] if rel.name != "__init__.py" else parts[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node, a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                yield node, ".".join(base + ([node.module] if node.module else []))
            else:
                yield node, node.module or ""


@functools.lru_cache(maxsize=None)
def _parsed(f: Path) -> ast.Module:
    """The syntax tree of a source file, parsed once per test process (the scans below read the same files)."""
    return ast.parse(f.read_text(encoding="utf-8"), filename=str(f))


def _sources(folder: Path) -> list[Path]:
    """The Python files under ``folder``, without installed third-party trees (tools/bids-validator/node_modules
    holds npm's own bundled Python: 43 000 files to walk, none of them the project's)."""
    out = []
    for d, dirs, files in os.walk(folder):
        dirs[:] = [x for x in dirs if x != "node_modules"]
        out += [Path(d) / f for f in files if f.endswith(".py")]
    return sorted(out)


def violations(root: Path) -> list[str]:
    out = []
    for top in PACKAGES:
        for f in _sources(root / top):
            rel = f.relative_to(root)
            module = ".".join(rel.with_suffix("").parts).removesuffix(".__init__")
            allowed = _rule(module)
            tree = _parsed(f)
            for node, name in _walk(tree, rel):
                target = _canon(name)
                if target.split(".")[0] not in PACKAGES or _permitted(target, allowed):
                    continue
                if (module, target) in {(_canon(a), _canon(b)) for a, b in EXCEPTIONS}:
                    continue
                out.append(f"{rel}:{node.lineno}: {_installed(module)} imports {name}")
    return out


def bare_imports(root: Path) -> list[str]:
    """Absolute imports of a layer by its folder name (``pipeline.x``) in the project and its tests, examples
    and tools: they must name ``stridelab.pipeline.x`` (relative imports are fine)."""
    out = []
    for top in (*PACKAGES, "tests", "examples", "tools"):
        for f in _sources(root / top):
            rel = f.relative_to(root)
            for node, name in _walk(_parsed(f), rel):
                if _bare(name) and not (isinstance(node, ast.ImportFrom) and node.level):
                    out.append(f"{rel}:{node.lineno}: {name} -> {NAMESPACE}.{name}")
    return out


def test_imports_flow_one_way():
    bad = violations(PROJECT_ROOT)
    assert not bad, "wrong-direction imports (DESIGN.md 'Layers'):\n" + "\n".join(bad)


def test_every_import_names_the_installed_package():
    bad = bare_imports(PROJECT_ROOT)
    assert not bad, "imports of a layer by its folder name (installed as stridelab.<layer>):\n" + "\n".join(bad)


def test_the_simulator_imports_nothing_from_estimators():
    hits = []
    for f in _sources(PROJECT_ROOT / "validation" / "simulator"):
        rel = f.relative_to(PROJECT_ROOT)
        hits += [f"{rel}:{node.lineno}: {name}" for node, name in _walk(_parsed(f), rel)
                 if _canon(name).split(".")[0] == "estimators"]
    assert not hits, hits


@pytest.mark.parametrize("package, source, expect", [
    ("estimators/orientation", "from stridelab.pipeline.config import x\n", "stridelab.estimators.orientation.bad imports stridelab.pipeline.config"),
    ("pipeline", "def f():\n    import stridelab.dashboard.figures\n", "pipeline.bad imports stridelab.dashboard.figures"),
    ("pipeline", "from stridelab.validation.bench import gait\n", "pipeline.bad imports stridelab.validation.bench"),
    ("dashboard", "from stridelab.pipeline.config import default_warehouse\n", "dashboard.bad imports stridelab.pipeline.config"),
    ("dashboard", "from stridelab.estimators.orientation import dcf\n", "dashboard.bad imports stridelab.estimators.orientation"),
    ("validation/simulator", "from stridelab.estimators.quaternion import quat_mul\n",
     "stridelab.validation.simulator.bad imports stridelab.estimators.quaternion"),
    ("warehouse", "from stridelab.reports.participant import build_report\n", "warehouse.bad imports stridelab.reports.participant"),
])
def test_the_checker_catches_a_wrong_direction_import(tmp_path, package, source, expect):
    """The scan itself: a wrong-direction import planted in a copy of the layout is reported."""
    for top in PACKAGES:
        (tmp_path / top).mkdir()
    d = tmp_path / package
    d.mkdir(parents=True, exist_ok=True)
    (d / "bad.py").write_text(source)
    assert any(expect in v for v in violations(tmp_path)), violations(tmp_path)


def test_the_checker_reports_a_bare_layer_import(tmp_path):
    for top in PACKAGES:
        (tmp_path / top).mkdir()
    (tmp_path / "tests").mkdir()
    bare = "from pipeline.config import x\n"               # namespace-rewrite: keep
    lazy = "def f():\n    import warehouse.store as s\n"   # namespace-rewrite: keep
    (tmp_path / "tests" / "test_x.py").write_text(bare + "from . import helpers\nfrom stridelab.pipeline import "
                                                  "config\nimport stridelab\n")
    (tmp_path / "validation" / "y.py").write_text(lazy)
    assert bare_imports(tmp_path) == [
        "validation/y.py:2: warehouse.store -> stridelab.warehouse.store",   # namespace-rewrite: keep
        "tests/test_x.py:1: pipeline.config -> stridelab.pipeline.config"]   # namespace-rewrite: keep


def test_allowed_imports_are_not_reported(tmp_path):
    for top in PACKAGES:
        (tmp_path / top).mkdir()
    (tmp_path / "dashboard" / "ok.py").write_text("from stridelab.warehouse import queries\nfrom stridelab.estimators.gait.evaluation "
                                                  "import match_events\nfrom stridelab.reports.normative import normative_band\n")
    (tmp_path / "validation" / "ok.py").write_text("from stridelab.pipeline.console import emit_json\n")
    (tmp_path / "validation" / "simulator").mkdir()
    (tmp_path / "validation" / "simulator" / "ok.py").write_text("from stridelab.studies.manifest import StudyManifest\n"
                                                                  "from . import _lab\n")
    assert violations(tmp_path) == []
