"""Every script of examples/ runs to the end and saves its figure (docs/examples.md shows them).

The examples read a StrideLab home (here the ``small_home`` fixture: the demo study cut to one participant, made
by the real simulator and pipeline) and the public data in ../shared/data; an example whose data are absent exits
with code 77 and the reason, and its test skips with that reason."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p for p in (ROOT / "examples").glob("*.py") if not p.name.startswith("_"))


def test_there_are_at_least_eight_examples_each_with_a_title_and_a_figure():
    assert len(EXAMPLES) >= 8
    for p in EXAMPLES:
        text = p.read_text()
        assert text.startswith('"""') and "\n===" in text.split('"""')[1], f"{p.name}: title + underline docstring"
        assert "out(" in text and "saved(" in text, f"{p.name}: saves its figure with _common.out / saved"


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs_and_saves_its_figure(script, small_home, tmp_path):
    env = {**os.environ, "STRIDELAB_HOME": str(small_home), "STRIDELAB_EXAMPLES_OUT": str(tmp_path),
           "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "examples")]), "MPLBACKEND": "Agg"}
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, cwd=tmp_path,
                       timeout=900)
    if r.returncode == 77:
        pytest.skip(r.stderr.strip().splitlines()[-1])
    assert r.returncode == 0, r.stderr[-3000:]
    figures = [line.split(" ", 1)[1] for line in r.stdout.splitlines() if line.startswith("saved ")]
    assert figures, r.stdout
    for f in figures:
        assert Path(f).parent == tmp_path and Path(f).stat().st_size > 2000, f
    assert "Warning" not in r.stderr, r.stderr[-2000:]


def test_the_readme_python_example_runs(small_home, tmp_path):
    """The README's 10-line example, on the small home (its one participant instead of the demo's P003)."""
    import re
    code = re.search(r"## From Python\n\n```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S).group(1)
    assert len([line for line in code.splitlines() if line.strip()]) <= 10
    code = code.replace('"stridelab-home', f'"{small_home}').replace("P003", "P001")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=600,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr[-3000:]
    assert "stride_length_m" in r.stdout and "strides, first IC at sample" in r.stdout
