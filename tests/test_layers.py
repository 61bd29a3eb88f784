"""Imports flow one way (DESIGN.md "Layers", issue 16 point 8): an AST scan of every module of the project.

estimators <- warehouse <- pipeline <- reports / validation <- stridelab (the command line that wires them);
dashboard reads the warehouse (and the reports, and the scorers ``estimators.<family>.evaluation``) only;
the simulator (``validation.simulator``) imports nothing from ``estimators`` (its ground truth is its own code).
Every ``import`` statement counts, including the lazy ones inside functions.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("estimators", "studies", "warehouse", "pipeline", "reports", "dashboard", "validation", "stridelab")

#: package (or sub-package: the longest prefix wins) -> project packages it may import
ALLOWED: dict[str, set[str]] = {
    "estimators": {"estimators"},
    "studies": {"studies"},
    "warehouse": {"warehouse", "estimators"},
    "pipeline": {"pipeline", "warehouse", "estimators", "studies"},
    "reports": {"reports", "warehouse", "estimators"},
    "dashboard": {"dashboard", "warehouse", "reports", "estimators.*.evaluation"},
    "validation": {"validation", "pipeline", "warehouse", "estimators", "studies", "reports", "dashboard"},
    "validation.simulator": {"validation.simulator", "studies"},
    "stridelab": set(PACKAGES),
}
#: entry points that may import upward: ``python -m pipeline`` is kept as an alias of ``python -m stridelab``
EXCEPTIONS = {("pipeline.__main__", "stridelab.cli")}


def _rule(module: str) -> set[str]:
    best = max((k for k in ALLOWED if module == k or module.startswith(k + ".")), key=len)
    return ALLOWED[best]


def _permitted(target: str, allowed: set[str]) -> bool:
    for a in allowed:
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


def violations(root: Path) -> list[str]:
    out = []
    for top in PACKAGES:
        for f in sorted((root / top).rglob("*.py")):
            rel = f.relative_to(root)
            module = ".".join(rel.with_suffix("").parts).removesuffix(".__init__")
            allowed = _rule(module)
            tree = ast.parse(f.read_text(encoding="utf-8"), filename=str(f))
            for node, target in _walk(tree, rel):
                if target.split(".")[0] not in PACKAGES or _permitted(target, allowed):
                    continue
                if (module, target) in EXCEPTIONS:
                    continue
                out.append(f"{rel}:{node.lineno}: {module} imports {target}")
    return out


def test_imports_flow_one_way():
    bad = violations(PROJECT_ROOT)
    assert not bad, "wrong-direction imports (DESIGN.md 'Layers'):\n" + "\n".join(bad)


def test_the_simulator_imports_nothing_from_estimators():
    hits = []
    for f in sorted((PROJECT_ROOT / "validation" / "simulator").rglob("*.py")):
        rel = f.relative_to(PROJECT_ROOT)
        hits += [f"{rel}:{node.lineno}: {name}" for node, name in _walk(ast.parse(f.read_text()), rel)
                 if name.split(".")[0] == "estimators"]
    assert not hits, hits


@pytest.mark.parametrize("package, source, expect", [
    ("estimators/orientation", "from pipeline.config import x\n", "estimators.orientation.bad imports pipeline.config"),
    ("pipeline", "def f():\n    import dashboard.figures\n", "pipeline.bad imports dashboard.figures"),
    ("pipeline", "from validation.bench import gait\n", "pipeline.bad imports validation.bench"),
    ("dashboard", "from pipeline.config import default_warehouse\n", "dashboard.bad imports pipeline.config"),
    ("dashboard", "from estimators.orientation import dcf\n", "dashboard.bad imports estimators.orientation"),
    ("validation/simulator", "from estimators.quaternion import quat_mul\n",
     "validation.simulator.bad imports estimators.quaternion"),
    ("warehouse", "from reports.participant import build_report\n", "warehouse.bad imports reports.participant"),
])
def test_the_checker_catches_a_wrong_direction_import(tmp_path, package, source, expect):
    """The scan itself: a wrong-direction import planted in a copy of the layout is reported."""
    for top in PACKAGES:
        (tmp_path / top).mkdir()
    d = tmp_path / package
    d.mkdir(parents=True, exist_ok=True)
    (d / "bad.py").write_text(source)
    assert any(expect in v for v in violations(tmp_path)), violations(tmp_path)


def test_allowed_imports_are_not_reported(tmp_path):
    for top in PACKAGES:
        (tmp_path / top).mkdir()
    (tmp_path / "dashboard" / "ok.py").write_text("from warehouse import queries\nfrom estimators.gait.evaluation "
                                                  "import match_events\nfrom reports.normative import normative_band\n")
    (tmp_path / "validation" / "ok.py").write_text("from pipeline.console import emit_json\n")
    (tmp_path / "validation" / "simulator").mkdir()
    (tmp_path / "validation" / "simulator" / "ok.py").write_text("from studies.manifest import StudyManifest\n"
                                                                  "from . import _lab\n")
    assert violations(tmp_path) == []
