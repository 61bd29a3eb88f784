"""One numba cache for every process of an installation, filled at install time.

Every kernel is ``@njit(cache=True)``; numba's default cache sits in ``__pycache__`` beside each source
file, so a fresh clone compiled every kernel on the user's clock (6.8-8.4 s in the first gait and
activity tasks of each ``make demo``). Inside a virtual environment the package points numba's own
configuration (``numba.config.CACHE_DIR``) at ``<venv>/var/cache/stridelab-numba``, unless the user set
``NUMBA_CACHE_DIR``, so the install step (``stridelab warm-kernels``, run by ``make install``) compiles each
kernel once and every later process, pool worker or Dask worker of that installation loads it from there
(each of them imports this package before it defines or loads a kernel). Outside a venv, or when the venv
is read-only, numba's default stays.

The directory is keyed by :func:`sources_key` (path, size and mtime of every module of the folders that define
kernels): numba checks a cached kernel only against its own source file, so a kernel that calls a kernel of
another module kept the callee's old machine code after that module changed (numba issue #6845), in a checkout
after an edit and in an installation after an upgrade. Any change of those modules now starts an empty cache
directory; ``stridelab warm-kernels`` removes the directories of other sources.

Nothing leaks out of the process: the environment is left as it was (``import stridelab.estimators`` does not set
``NUMBA_CACHE_DIR`` for the process or its children). Numba chooses a kernel's cache directory when the
``@njit(cache=True)`` decorator runs and re-reads its environment variables only when one of them changes,
so a value set here holds for every kernel module imported afterwards.
"""
from __future__ import annotations

import hashlib
import importlib.abc
import importlib.machinery
import os
import sys
from pathlib import Path

ENV = "NUMBA_CACHE_DIR"
#: the folders (relative to the folder holding the layers) whose modules define numba kernels; a test checks that
#: no kernel is defined elsewhere
KERNEL_DIRS = ("estimators", "pipeline/formats", "pipeline/ingest")


def sources_key(root: Path | None = None) -> str:
    """A short key of the kernel sources: path, size and mtime (what numba's own index compares) of every module
    under :data:`KERNEL_DIRS` of ``root`` (the repository in a checkout, ``site-packages/stridelab`` once
    installed). About 2 ms: stat calls only."""
    root = Path(__file__).resolve().parent.parent if root is None else Path(root)
    h = hashlib.sha256()
    for sub in KERNEL_DIRS:
        top = root / sub
        for dirpath, dirnames, filenames in os.walk(top):
            dirnames[:] = sorted(d for d in dirnames if d != "__pycache__")
            rel = Path(dirpath).relative_to(root).as_posix()
            for name in sorted(filenames):
                if name.endswith(".py"):
                    st = os.stat(os.path.join(dirpath, name))
                    h.update(f"{rel}/{name} {st.st_size} {st.st_mtime_ns}\n".encode())
    return h.hexdigest()[:16]


def venv_cache_dir() -> Path | None:
    """The installation's shared cache directory for the current kernel sources (None outside a writable virtual
    environment)."""
    if sys.prefix == sys.base_prefix:
        return None
    # one folder per package layout: a cached kernel refers to the kernels it calls by module name, so entries
    # written when the layers were top-level packages (``estimators``) would not load as ``stridelab.estimators``
    d = Path(sys.prefix) / "var" / "cache" / "stridelab-numba" / __package__ / sources_key()
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
    config = sys.modules.get("numba.core.config")
    if config is not None:                # numba is already loaded: set it now
        config.CACHE_DIR = str(d)
    else:                                 # set it when numba loads, so importing estimators stays light
        sys.meta_path.insert(0, _SetCacheDirOnLoad(str(d)))
    return str(d)


class _SetCacheDirOnLoad(importlib.abc.MetaPathFinder):
    """Sets ``numba.core.config.CACHE_DIR`` right after numba executes that module (before any ``@njit`` of ours
    runs), then removes itself: ``import stridelab.estimators`` (and ``pipeline``, which the engines' workers import before
    the heavy libraries) does not import numba just to configure it."""

    def __init__(self, cache_dir: str):
        self.cache_dir = cache_dir

    def find_spec(self, fullname, path, target=None):
        if fullname != "numba.core.config":
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        exec_module, cache_dir = spec.loader.exec_module, self.cache_dir

        def exec_and_set(module):
            exec_module(module)
            module.CACHE_DIR = cache_dir

        spec.loader.exec_module = exec_and_set
        return spec


CACHE_DIR = configure()
