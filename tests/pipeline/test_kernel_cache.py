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
    from stridelab.estimators._numba_cache import sources_key
    assert numba_dir == str(Path(sys.prefix) / "var" / "cache" / "stridelab-numba" / "stridelab.estimators" / sources_key())


# ``stridelab warm-kernels`` then every stage in a fresh process without compiling: tests/test_install.py
# (test_after_warm_kernels_every_stage_runs_without_compiling) checks it in a clean installation, whose numba cache
# starts empty, so the kernels are compiled once for both checks instead of once for each.
