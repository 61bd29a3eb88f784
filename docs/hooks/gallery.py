"""MkDocs hook: the examples gallery, one page per script of ``examples/``, generated at every build.

Each page is the script's docstring (title and text), its figure and its full source. The figures are the PNGs
the scripts save, kept in ``docs/examples/img/`` (``make docs-figures`` regenerates them from the demo home;
``tests/test_examples.py`` runs every script on each test run)."""
from __future__ import annotations

import ast
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


def _scripts() -> list[Path]:
    return sorted(p for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))


def _page(script: Path) -> tuple[str, str]:
    src = script.read_text()
    doc = ast.get_docstring(ast.parse(src)) or script.stem
    lines = doc.splitlines()
    title, body = lines[0].strip(), "\n".join(lines[2:]).strip()
    code = src.split('"""', 2)[2].lstrip("\n")
    img = f"img/{script.stem}.png"
    fig = f"![{title}]({img})\n\n" if (ROOT / "docs" / "examples" / img).exists() else ""
    md = (f"# {title}\n\n{body}\n\n{fig}"
          f"Run it: `python examples/{script.name}` (after `make demo ARGS=--no-serve`; figures go to "
          f"`examples/output/`).\n\n```python\n{code}```\n")
    return title, md


def on_files(files, config):
    rows = []
    for script in _scripts():
        title, md = _page(script)
        files.append(File.generated(config, f"examples/{script.stem}.md", content=md))
        rows.append(f"| [{title}]({script.stem}.md) | `examples/{script.name}` |")
    index = ("# Examples\n\nShort scripts that run as they are (each saves its figure); every one is executed by "
             "`tests/test_examples.py`. They read the demo home (`make demo ARGS=--no-serve`, or set "
             "`STRIDELAB_HOME`) and the public data sets in `../shared/data` (`STRIDELAB_DATA`).\n\n"
             "| example | script |\n|---|---|\n" + "\n".join(rows) + "\n")
    files.append(File.generated(config, "examples/index.md", content=index))
    return files



def on_page_content(html, page, config, files):
    """The CLI reference: click's ``\\b`` example blocks arrive as one paragraph ("Examples: stridelab … stridelab
    …"); show them as the command lines they are."""
    import re
    if page.file.src_uri != "cli.md":
        return html

    def block(m):
        cmds = [c.strip() for c in re.split(r"\s(?=stridelab\s|ros2\s)", m.group(1)) if c.strip()]
        return "<p>Examples:</p>\n<pre><code>" + "\n".join(cmds) + "</code></pre>"
    return re.sub(r"<p>Examples:\s*(.*?)</p>", block, html, flags=re.S)
