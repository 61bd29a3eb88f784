# StrideLab: two commands for a newcomer (README "Quick start").
#   make demo   create .venv, install the pinned dependencies, run `stridelab demo`, which compiles the numba
#               kernels once (`stridelab warm-kernels`, into .venv/var/cache/stridelab-numba) in a second
#               process while it simulates the demo study, then runs the pipeline
#   make install  the same installation, kernels compiled (`stridelab warm-kernels`) and the packages' bytecode
#               compiled once before it returns (benches and nightly runs start many processes)
#   make test   install if missing (with the docs tools and the BIDS validator), compile the packages' bytecode
#               once, run the test suite (docs build and examples included)
#   make docs   build the documentation site into site/ (mkdocs build --strict)
#   make test-fast  the same without the slow, real-data and browser tests (the edit loop)
# Variables: PY=python3.11 (interpreter), ARGS="--no-serve" (demo options), PYTEST_ARGS="-m 'not slow'",
#   XDIST= (the tests in one process instead of two pytest-xdist workers), INSTALLER=pip (skip uv).
# Packages are installed by uv (UV_VERSION, from the package index through pip): 6 s instead of pip's 90 s for
# requirements.lock on 2 cores (download 18 s, unpack 26 s, bytecode 45 s); without bytecode compilation,
# which Python then does for the modules a process imports. If uv cannot be installed or fails, pip does it.
# The project itself is installed editable in setuptools' "lenient" mode (EDITABLE): an import hook maps
# stridelab.pipeline -> pipeline/ and so on (setup.py), so `import stridelab.pipeline` works from any directory,
# the repository root included, and new modules need no reinstall; docs/architecture.md "One installed name".

PY ?= python3
VENV := .venv
DEPS := $(VENV)/.deps-stamp
STAMP := $(VENV)/.installed-stamp
BYTECODE := $(VENV)/.bytecode-stamp
UV_VERSION := 0.13.8
INSTALLER ?= uv
EDITABLE := editable_mode=lenient
ARGS ?=
PYTEST_ARGS ?=
# the tests on two worker processes (pytest-xdist; tests/conftest.py keeps each module, and the modules sharing an
# expensive session fixture, on one worker); XDIST= runs them in one process
XDIST ?= -n 2 --dist loadgroup

.PHONY: demo test test-fast install browser clean docs docs-tools bids-validator anchors-mobgap

$(DEPS): pyproject.toml setup.py requirements.lock
	@$(PY) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null || \
	  { echo "error: StrideLab needs Python >= 3.11; '$(PY)' is $$($(PY) --version 2>&1). Run: make PY=python3.11 ..." >&2; exit 1; }
	@test -x $(VENV)/bin/python || $(PY) -m venv $(VENV) 2>/dev/null || { \
	  rm -rf $(VENV); \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "python venv support missing: installing python3-venv with apt-get" >&2; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null && $(PY) -m venv $(VENV); \
	  else \
	    echo "error: '$(PY) -m venv' failed; install venv support first: sudo apt-get install python3-venv" >&2; exit 1; \
	  fi; }
	@if [ "$(INSTALLER)" = uv ] && { $(VENV)/bin/python -m pip install --quiet uv==$(UV_VERSION) >/dev/null 2>&1 || \
	    { echo "note: could not install uv $(UV_VERSION) with pip" >&2; false; }; } && \
	  $(VENV)/bin/uv pip install --quiet --python $(VENV)/bin/python -r requirements.lock && \
	  $(VENV)/bin/uv pip install --quiet --python $(VENV)/bin/python --no-deps -C $(EDITABLE) -e . ; then \
	  echo "installed requirements.lock with uv $(UV_VERSION)" >&2; \
	else \
	  [ "$(INSTALLER)" != uv ] || echo "note: installing with uv $(UV_VERSION) failed; installing with pip instead (slower: about 1.5 min)" >&2; \
	  $(VENV)/bin/python -m pip install --quiet --upgrade pip && \
	  $(VENV)/bin/python -m pip install --quiet -r requirements.lock && \
	  $(VENV)/bin/python -m pip install --quiet --no-deps --config-settings $(EDITABLE) -e . ; \
	fi
	@touch $@

$(STAMP): $(DEPS)
	@echo "compiling the numba kernels once into the venv's shared cache (stridelab warm-kernels) …" >&2
	$(VENV)/bin/stridelab warm-kernels
	@touch $@

# Bytecode of every installed module, once (uv installs without it): the test suite, the benches and every
# run's workers start many processes, and with PYTHONDONTWRITEBYTECODE set each would compile its imports
# again (about 2 s of CPU per process for scipy, pandas and DuckDB).
$(BYTECODE): $(DEPS)
	@$(VENV)/bin/python -m compileall -q -j 0 $(VENV)/lib >/dev/null || true
	@touch $@

install: $(STAMP) $(BYTECODE)

demo: $(DEPS)
	$(VENV)/bin/stridelab demo $(ARGS)

test: $(STAMP) $(BYTECODE) browser docs-tools bids-validator
	$(VENV)/bin/python -m pytest $(XDIST) $(PYTEST_ARGS)

# The edit loop: everything that needs neither the public data, a browser nor more than a few seconds.
test-fast: $(STAMP) $(BYTECODE)
	$(VENV)/bin/python -m pytest $(XDIST) -q -m "not slow and not realdata and not browser" $(PYTEST_ARGS)

# The documentation tools (MkDocs, Material, mkdocstrings, mkdocs-click), pinned in requirements-docs.lock; the
# docs test (tests/test_docs.py) builds the site with --strict.
DOCS_STAMP := $(VENV)/.docs-stamp
$(DOCS_STAMP): $(DEPS) requirements-docs.lock
	@{ [ "$(INSTALLER)" = uv ] && [ -x $(VENV)/bin/uv ] && \
	  $(VENV)/bin/uv pip install --quiet --python $(VENV)/bin/python -r requirements-docs.lock; } || \
	  $(VENV)/bin/python -m pip install --quiet -r requirements-docs.lock
	@touch $@
docs-tools: $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

# The official BIDS validator (npm bids-validator, pinned by tools/bids-validator/package-lock.json) for the
# Motion-BIDS export test; skipped with a note where Node.js/npm are missing (the test then skips too).
BIDS_VALIDATOR := tools/bids-validator/node_modules/.bin/bids-validator
$(BIDS_VALIDATOR): tools/bids-validator/package-lock.json
	@command -v npm >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && \
	  echo "installing Debian's nodejs and npm for the BIDS validator" >&2 && \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm >/dev/null) || true; }
	@if command -v npm >/dev/null 2>&1; then \
	  echo "installing the BIDS validator (npm ci in tools/bids-validator) …" >&2; \
	  (cd tools/bids-validator && npm ci --no-audit --no-fund --loglevel=error >/dev/null) && touch $@ || \
	    echo "note: could not install the BIDS validator; the BIDS export test will skip" >&2; \
	else echo "note: npm not found (sudo apt-get install nodejs npm); the BIDS export test will skip" >&2; fi
bids-validator: $(BIDS_VALIDATOR)

# Debian's Chromium for the dashboard's real-browser test; skipped (with a message) where apt is unavailable.
browser:
	@{ command -v chromium >/dev/null 2>&1 && command -v pdftoppm >/dev/null 2>&1; } || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing Debian's chromium and poppler-utils for the browser and PDF tests" >&2; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium poppler-utils >/dev/null) || \
	      echo "warning: could not install chromium; the browser test will be skipped" >&2; \
	  else \
	    echo "note: chromium/pdftoppm not found (sudo apt-get install chromium poppler-utils); those tests will be skipped" >&2; \
	  fi; }

# mobgap (the Mobilise-D reference pipeline), the anchor of `stridelab bench trunk-gait`, in an ISOLATED venv: its
# pins (pandas 3, numpy 2.4, scikit-learn 1.6.1 for its pickled models) are not StrideLab's; the bench runs it in a
# subprocess (validation/anchors/mobgap_runner.py) and prints `anchor: null` with the reason when it is absent.
MOBGAP_VENV := .venv-mobgap
$(MOBGAP_VENV)/.installed-stamp: validation/anchors/mobgap-requirements.txt
	@$(PY) -m venv $(MOBGAP_VENV)
	$(MOBGAP_VENV)/bin/python -m pip install --quiet -r validation/anchors/mobgap-requirements.txt
	@touch $@

anchors-mobgap .venv-mobgap: $(MOBGAP_VENV)/.installed-stamp

clean:
	rm -rf $(VENV) $(MOBGAP_VENV) stridelab-home .pytest_cache site tools/bids-validator/node_modules
