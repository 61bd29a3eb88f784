"""One numba cache for every process of an installation, filled at install time.

Every kernel is ``@njit(cache=True)``; numba's default cache sits in ``__pycache__`` beside each source
file, so a fresh clone compiled every kernel on the user's clock (6.8-8.4 s in the first gait and
activity tasks of each ``make demo``). Inside a virtual environment the package points
``NUMBA_CACHE_DIR`` at ``<venv>/var/cache/stridelab-numba`` (unless the user set it), so the install
step (``stridelab warm-kernels``, run by ``make install``) compiles each kernel once and every later
process, pool worker or Dask worker of that installation loads it from there. Outside a venv, or when
the venv is read-only, numba's default stays.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

ENV = "NUMBA_CACHE_DIR"


def venv_cache_dir() -> Path | None:
    """The installation's shared cache directory (None outside a writable virtual environment)."""
    if sys.prefix == sys.base_prefix:
        return None
    d = Path(sys.prefix) / "var" / "cache" / "stridelab-numba"
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return d if os.access(d, os.W_OK) else None


def configure() -> str | None:
    """Set ``NUMBA_CACHE_DIR`` for this process and its children (before the first kernel is defined);
    returns the directory numba will use (None: numba's default)."""
    if not os.environ.get(ENV):
        d = venv_cache_dir()
        if d is None:
            return None
        os.environ[ENV] = str(d)
    if "numba" in sys.modules:          # numba read its config already: tell it too
        from numba.core import config
        config.CACHE_DIR = os.environ[ENV]
    return os.environ[ENV]


CACHE_DIR = configure()
