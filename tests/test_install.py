"""``pip install .`` into a clean virtual environment (issue #45, point 5): the distribution puts one name,
``stridelab``, at the top of site-packages; the layers import as ``stridelab.<layer>`` and not by their folder
names; the installed command line runs a small study end to end and serves the dashboard from the installed files.

Everything runs outside the repository (a copy of the sources is installed, not linked; the commands run in a
temporary folder without PYTHONPATH), so nothing can be found through the checkout. The dependencies come from
requirements.lock (with uv when the project venv has it, from its cache: seconds); the package itself with pip.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("estimators", "warehouse", "pipeline", "reports", "dashboard", "validation", "studies")
NOT_SOURCES = shutil.ignore_patterns(".venv*", ".git", "build", "*.egg-info", "__pycache__", "site", "node_modules",
                                     "stridelab-home", ".pytest_cache", "examples", "docs", "tests")

pytestmark = pytest.mark.slow


def _run(args, cwd, env, timeout=900, check=True):
    r = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if check:
        assert r.returncode == 0, f"{args}: {r.stderr[-3000:]}"
    return r


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(python of a clean venv with StrideLab installed from a copy of the sources, a scratch folder, env)."""
    base = tmp_path_factory.mktemp("install")
    src = base / "src"
    shutil.copytree(ROOT, src, ignore=NOT_SOURCES)
    venv = base / "venv"
    _run([sys.executable, "-m", "venv", venv], base, None)
    py = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "VIRTUAL_ENV")}
    uv = Path(sys.prefix) / "bin" / "uv"
    if uv.exists():
        _run([uv, "pip", "install", "--quiet", "--python", py, "-r", src / "requirements.lock"], base, env)
    else:
        _run([py, "-m", "pip", "install", "--quiet", "-r", src / "requirements.lock"], base, env)
    _run([py, "-m", "pip", "install", "--quiet", "--no-deps", "."], src, env)
    work = base / "work"
    work.mkdir()
    return py, work, env


@pytest.fixture(scope="module")
def warmed(installed) -> dict:
    """``stridelab warm-kernels --json`` of the clean installation (what ``make install`` runs after installing):
    its numba cache is the new venv's own, empty before (no NUMBA_CACHE_DIR in the environment)."""
    py, work, env = installed
    r = _run([py.parent / "stridelab", "warm-kernels", "--json"], work, env, timeout=1800)
    return json.loads(r.stdout)


def test_only_stridelab_at_the_top_of_site_packages(installed):
    py, work, env = installed
    code = ("import importlib.metadata as m, json; "
            "print(json.dumps(sorted({f.parts[0] for f in m.files('stridelab') if f.parts[0] != '..'})))")
    tops = json.loads(_run([py, "-c", code], work, env).stdout)       # ("..": the console script in bin/)
    assert tops == ["stridelab", "stridelab-0.1.0.dist-info"], tops
    site = Path(_run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], work, env).stdout.strip())
    assert not [p.name for p in site.iterdir() if p.name in LAYERS]


def test_layers_import_only_under_the_namespace(installed):
    py, work, env = installed
    for layer in LAYERS:
        bare = _run([py, "-c", f"import {layer}"], work, env, check=False)
        assert bare.returncode != 0 and f"No module named '{layer}'" in bare.stderr, (layer, bare.stderr)
    r = _run([py, "-c", "import importlib, stridelab; "
                        f"print([importlib.import_module('stridelab.' + n).__name__ for n in {LAYERS!r}])"], work, env)
    assert r.stdout.strip() == str([f"stridelab.{n}" for n in LAYERS])
    # the package data ships: migrations, study manifests, the activity model, the live pages, provenance
    r = _run([py, "-c", "from importlib import resources as r; "
                        "print(sorted(f.name for f in r.files('stridelab.warehouse.migrations').iterdir() "
                        "if f.name.endswith('.sql'))[0], r.files('stridelab.studies').joinpath('demo/study.toml')"
                        ".is_file(), r.files('stridelab.pipeline').joinpath('models/activity_window_lr.json')"
                        ".is_file(), r.files('stridelab.validation').joinpath('provenance.toml').is_file())"],
             work, env)
    assert r.stdout.split() == ["001_initial.sql", "True", "True", "True"], r.stdout


def test_after_warm_kernels_every_stage_runs_without_compiling(installed, warmed):
    """The install step compiles each kernel once into the installation's cache (a small study through ingest and
    every stage); another participant's sessions through every stage in a fresh process then compile nothing.
    Here rather than in tests/pipeline/test_kernel_cache.py: the clean installation's cache starts empty, so the
    kernels are compiled once for this and the installed command line's run below, not once for each."""
    from stridelab.pipeline.stages import registry
    py, work, env = installed
    venv = py.parent.parent
    assert Path(warmed["cache_dir"]).parent == venv / "var" / "cache" / "stridelab-numba" / "stridelab.estimators", warmed
    assert warmed["signatures_compiled"] >= 15 and warmed["signatures_from_cache"] == 0, warmed
    # every stage ran ('ok') on the small study, except those about a kind of recording it has none of (a live
    # session's: Stage.applies)
    stages = {s.name for s in registry() if s.applies is None}
    assert {k.split(":")[0] for k, n in warmed["stage_status"].items() if k.endswith(":ok")} == stages, warmed
    assert warmed["stage_runs"] == sum(warmed["stage_status"].values())
    r = _run([py, "-c", "from stridelab.warm import is_warm; print(is_warm())"], work, env)
    assert r.stdout.strip() == "True"
    code = ("import json, sys; from pathlib import Path; from stridelab.warm import run_small_study; "
            "print(json.dumps(run_small_study(Path(sys.argv[1]), index=1, hours=1.0, start_local='12:00')))")
    r = _run([py, "-c", code, work / "second"], work, env, timeout=1800)
    second = json.loads(r.stdout.strip().splitlines()[-1])
    assert second["stage_status"] == warmed["stage_status"] and second["stage_runs"] == warmed["stage_runs"]
    assert second["signatures_compiled"] == 0, second["compiled"]
    assert second["signatures_from_cache"] >= 15


def test_the_installed_command_runs_a_small_study_and_serves_the_dashboard(installed, warmed):
    py, work, env = installed
    cli = py.parent / "stridelab"
    assert "Examples" in _run([cli, "--help"], work, env).stdout
    assert "trunk-gait" in _run([cli, "bench", "--help"], work, env).stdout     # benches found under the namespace
    _run([cli, "simulate", work / "inbox", "--participants", "1", "--hours", "0.05", "--json"], work, env)
    r = _run([cli, "run", "--inbox", work / "inbox", "--warehouse", work / "wh", "--json", "--no-reports"], work, env,
             timeout=1800)
    summary = json.loads(r.stdout)
    assert not summary["failed"] and not summary["quarantined"], summary
    # the app file of the installed package, as `stridelab dashboard` runs it (AppTest: the page's imports resolve)
    app = _run([py, "-c", "from importlib.util import find_spec; "
                          "print(find_spec('stridelab.dashboard').origin)"], work, env).stdout.strip()
    assert Path(app).parent.parent.name == "stridelab" and "site-packages" in app
    code = ("from streamlit.testing.v1 import AppTest\n"
            f"at = AppTest.from_file({str(Path(app).with_name('app.py'))!r}, default_timeout=120)\n"
            "at.run()\nassert not at.exception, [e.value for e in at.exception]\n"
            "print(' | '.join(m.label for m in at.metric))\n")
    r = _run([py, "-c", code], work, {**env, "STRIDELAB_WAREHOUSE": str(work / "wh")})
    assert "Participants" in r.stdout, r.stdout
    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    # its own process group, so that the teardown's fallback can stop everything it might have started
    proc = subprocess.Popen([str(cli), "dashboard", "--warehouse", str(work / "wh"), "--port", str(port)], cwd=work,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    try:
        for _ in range(240):
            if proc.poll() is not None:
                pytest.fail(f"stridelab dashboard exited {proc.returncode}: {proc.stdout.read()[-2000:]}")
            try:
                with urllib.request.urlopen(f"http://localhost:{port}/_stcore/health", timeout=2) as resp:
                    assert resp.read().decode() == "ok"
                    break
            except OSError:
                time.sleep(0.5)
        else:
            pytest.fail("stridelab dashboard did not answer within 2 minutes")
        # SIGTERM to the command's own process (as a service manager sends it) stops the server: no orphan
        proc.terminate()
        proc.wait(timeout=30)
        with pytest.raises(OSError):
            urllib.request.urlopen(f"http://localhost:{port}/_stcore/health", timeout=2)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=10)
