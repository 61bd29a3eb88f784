"""``make demo`` leaves the kernel compilation to ``stridelab demo``, which runs ``stridelab warm-kernels`` in a
second process while it simulates, and only when this installation's cache is not warm for the current sources;
the runner builds the reports on its worker processes, so the report builder must pickle."""
from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

MARKER = """
from stridelab.warm import is_warm, write_marker
a = is_warm()
write_marker(44)
print(a, is_warm())
"""


def test_the_marker_says_warm_only_after_a_warm_up(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(ROOT)}
    (tmp_path / "cache").mkdir()
    r = subprocess.run([sys.executable, "-c", MARKER], capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["False", "True"]
    assert (tmp_path / "cache" / "warm-kernels.json").is_file()
    assert not list((tmp_path / "cache").glob(".*tmp*"))


def test_the_fingerprint_follows_the_kernel_sources(tmp_path):
    from stridelab.estimators._numba_cache import KERNEL_DIRS, sources_key
    from stridelab.warm import fingerprint
    for sub in KERNEL_DIRS:
        (tmp_path / sub).mkdir(parents=True)
        (tmp_path / sub / "k.py").write_text("x = 1\n")
    a, key = fingerprint(tmp_path), sources_key(tmp_path)
    assert fingerprint(tmp_path) == a and sources_key(tmp_path) == key
    f = tmp_path / KERNEL_DIRS[0] / "k.py"
    st = f.stat()
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))       # edited: numba recompiles, so must the demo
    assert fingerprint(tmp_path) != a and sources_key(tmp_path) != key
    (tmp_path / KERNEL_DIRS[1] / "new.py").write_text("")
    assert fingerprint(tmp_path) != a
    b = sources_key(tmp_path)
    (tmp_path / "pipeline" / "stage.py").write_text("")              # a module with no kernel: the cache stays
    assert sources_key(tmp_path) == b


def test_every_numba_kernel_is_defined_under_the_folders_that_key_the_cache():
    """A kernel defined elsewhere would not change the cache directory when edited: a kernel of another module
    calling it would keep its old machine code (numba issue #6845)."""
    import re
    from stridelab.estimators._numba_cache import KERNEL_DIRS
    layers = ("estimators", "pipeline", "warehouse", "reports", "dashboard", "validation", "studies", "stridelab")
    kernel = re.compile(r"@(numba\.)?(njit|jit)\b|=\s*(numba\.)?(njit|jit)\(")
    outside = [str(f.relative_to(ROOT)) for layer in layers for f in (ROOT / layer).rglob("*.py")
               if kernel.search(f.read_text()) and not any(f.relative_to(ROOT).as_posix().startswith(d + "/")
                                                           for d in KERNEL_DIRS)]
    assert outside == [], f"kernels outside {KERNEL_DIRS}: {outside}; add their folder to KERNEL_DIRS"


def test_the_demo_starts_the_warm_up_only_when_needed(monkeypatch):
    from stridelab import cli, warm
    started = []

    class FakeProc:
        returncode = 0

        def __init__(self, cmd):
            started.append(cmd)

        def wait(self):
            return 0

        def poll(self):
            return 0
    monkeypatch.setattr(subprocess, "Popen", FakeProc)
    monkeypatch.setattr(warm, "is_warm", lambda: True)
    assert cli._start_warm_kernels() is None and started == []
    monkeypatch.setattr(warm, "is_warm", lambda: False)
    p = cli._start_warm_kernels()
    cli._finish_warm_kernels(p)
    assert started == [[sys.executable, "-m", "stridelab", "warm-kernels"]]


def test_the_report_builder_pickles_for_the_worker_processes(tmp_path):
    from stridelab.pipeline.reports import _picklable
    from stridelab.cli import _report_builder
    b = _report_builder(tmp_path / "wh")
    assert _picklable(b) and pickle.loads(pickle.dumps(b)).args == (tmp_path / "wh",)
    assert not _picklable(lambda s, p, o: {})
