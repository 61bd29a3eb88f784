"""One numba cache for every process of an installation, filled at install time.

Every kernel is ``@njit(cache=True)``; numba's default cache sits in ``__pycache__`` beside each source
file, so a fresh clone compiled every kernel on the user's clock (6.8-8.4 s in the first gait and
activity tasks of each ``make demo``). Inside a virtual environment the package points numba's own
configuration (``numba.config.CACHE_DIR``) at ``<venv>/var/cache/stridelab-numba``, unless the user set
``NUMBA_CACHE_DIR``, so the install step (``stridelab warm-kernels``, run by ``make install``) compiles each
kernel once and every later process, pool worker or Dask worker of that installation loads it from there
(each of them imports this package before it defines or loads a kernel). Outside a venv, or when the venv
is read-only, numba's default stays.

Nothing leaks out of the process: the environment is left as it was (``import estimators`` does not set
``NUMBA_CACHE_DIR`` for the process or its children). Numba chooses a kernel's cache directory when the
``@njit(cache=True)`` decorator runs and re-reads its environment variables only when one of them changes,
so a value set here holds for every kernel module imported afterwards.
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
    """Point numba's cache of this process at the installation's shared directory (before the first kernel
    is defined); returns the directory numba will use (None: numba's default, beside each source file).
    A ``NUMBA_CACHE_DIR`` the user set wins (numba reads it itself)."""
    if os.environ.get(ENV):
        return os.environ[ENV]
    d = venv_cache_dir()
    if d is None:
        return None
    from numba.core import config      # the kernels import numba anyway; this only comes first
    config.CACHE_DIR = str(d)
    return str(d)


CACHE_DIR = configure()
