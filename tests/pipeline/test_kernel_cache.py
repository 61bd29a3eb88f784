"""Numba kernels are compiled once per installation: a second fresh process loads them from the shared cache.

Timing-free: numba's dispatcher statistics (``cache_misses`` = compiled in this process, ``cache_hits`` =
loaded from the cache) and the index files in the cache directory."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from stridelab.pipeline.stages import registry

ROOT = Path(__file__).resolve().parents[2]

KERNEL = """
import json, numpy as np
from stridelab.estimators._numba_cache import CACHE_DIR
from stridelab.estimators.activity._kernels import second_sums
second_sums(np.ones((500, 3)), 100, 5)
st = second_sums.stats
print(json.dumps({"cache_dir": CACHE_DIR, "misses": sum(st.cache_misses.values()),
                  "hits": sum(st.cache_hits.values())}))
"""


def _py(code: str, cache: Path, *args) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, env=env,
                       cwd=ROOT, timeout=900)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_a_second_fresh_process_loads_the_kernel_instead_of_compiling(tmp_path):
    cache = tmp_path / "numba-cache"
    a = _py(KERNEL, cache)
    assert a == {"cache_dir": str(cache), "misses": 1, "hits": 0}
    assert list(cache.rglob("_kernels.second_sums-*.nbi")) and list(cache.rglob("_kernels.second_sums-*.nbc"))
    b = _py(KERNEL, cache)
    assert b == {"cache_dir": str(cache), "misses": 0, "hits": 1}


def test_the_package_points_numba_at_the_venv_cache():
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    r = subprocess.run([sys.executable, "-c", "import os, stridelab.pipeline, numba; "
                        "print(os.environ.get('NUMBA_CACHE_DIR')); print(numba.config.CACHE_DIR)"],
                       capture_output=True, text=True, env={**env, "PYTHONPATH": str(ROOT)}, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    env_dir, numba_dir = r.stdout.split()
    assert env_dir == "None"      # numba's own config is set; the environment of the process and its children is not
    if sys.prefix == sys.base_prefix:
        pytest.skip("not running in a virtual environment: numba keeps its default cache")
    assert numba_dir == str(Path(sys.prefix) / "var" / "cache" / "stridelab-numba" / "stridelab.estimators")


@pytest.mark.slow
def test_after_warm_kernels_every_stage_runs_without_compiling(tmp_path):
    """``stridelab warm-kernels`` (the install step), then another participant's sessions through ingest and
    every stage in a fresh process: nothing is compiled there."""
    cache = tmp_path / "numba-cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-m", "stridelab", "warm-kernels", "--json"], capture_output=True, text=True,
                       env=env, cwd=ROOT, timeout=1800)
    assert r.returncode == 0, r.stderr
    warm = json.loads(r.stdout)
    assert warm["cache_dir"] == str(cache) and warm["signatures_compiled"] >= 15
    # every stage ran ('ok') on the small study, except those about a kind of recording it has none of (a live
    # session's: Stage.applies)
    stages = {s.name for s in registry() if s.applies is None}
    assert {k.split(":")[0] for k, n in warm["stage_status"].items() if k.endswith(":ok")} == stages, warm
    assert warm["stage_runs"] == sum(warm["stage_status"].values())
    assert _py("import json; from stridelab.warm import is_warm; print(json.dumps(is_warm()))", cache) is True
    code = ("import json, sys; from pathlib import Path; from stridelab.warm import run_small_study; "
            "print(json.dumps(run_small_study(Path(sys.argv[1]), index=1, hours=1.0, start_local='12:00')))")
    second = _py(code, cache, tmp_path / "second")
    assert second["stage_status"] == warm["stage_status"] and second["stage_runs"] == warm["stage_runs"]
    assert second["signatures_compiled"] == 0, second["compiled"]
    assert second["signatures_from_cache"] >= 15
