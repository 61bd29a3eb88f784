"""The documentation: the MkDocs site builds with --strict (no warning, no broken link, every page in the nav, the
API reference and the CLI reference generated from the code), and the README links every docs page."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _nav_pages() -> set[str]:
    text = (ROOT / "mkdocs.yml").read_text()
    nav = text[text.index("\nnav:"):]
    return set(re.findall(r"([\w/.-]+\.md)\s*$", nav, flags=re.M))


def test_every_docs_page_and_every_example_is_in_the_nav():
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    examples = {f"examples/{p.stem}.md" for p in (ROOT / "examples").glob("*.py") if not p.name.startswith("_")}
    missing = (pages | examples | {"examples/index.md"}) - _nav_pages()
    assert not missing, f"add these to the nav of mkdocs.yml: {sorted(missing)}"


def test_the_readme_links_every_docs_page():
    readme = (ROOT / "README.md").read_text()
    linked = set(re.findall(r"\]\((docs/[\w/.-]+\.md)", readme))
    pages = {f"docs/{p.relative_to(DOCS).as_posix()}" for p in DOCS.glob("*.md")}
    assert pages - linked == set(), f"README.md does not link: {sorted(pages - linked)}"
    for link in re.findall(r"\]\(((?:docs|examples)/[^)#\s]+)", readme):
        assert (ROOT / link).exists(), f"README links a missing file: {link}"


@pytest.mark.slow
def test_the_site_builds_strictly(tmp_path):
    pytest.importorskip("mkdocs", reason="docs tools not installed: make docs-tools (requirements-docs.lock)")
    pytest.importorskip("mkdocstrings", reason="docs tools not installed: make docs-tools (requirements-docs.lock)")
    pytest.importorskip("mkdocs_click", reason="docs tools not installed: make docs-tools (requirements-docs.lock)")
    site = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
                       capture_output=True, text=True, cwd=ROOT, timeout=900,
                       env={**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr[-4000:]
    assert "WARNING" not in r.stderr, r.stderr[-4000:]
    # the generated parts are there: API reference from the docstrings, CLI reference from click, the gallery
    api = (site / "api" / "stridelab" / "index.html").read_text()
    assert "read_recording" in api and "TableMissing" in api
    assert "sampling_rate_hz" in (site / "api" / "orientation" / "index.html").read_text()
    cli = (site / "cli" / "index.html").read_text()
    for cmd in ("stridelab export bids", "stridelab run", "stridelab demo"):
        assert cmd in cli, cmd
    gallery = (site / "examples" / "index.html").read_text()
    assert gallery.count("examples/") >= 8
