# StrideLab: two commands for a newcomer (README "Quick start").
#   make demo   create .venv, install the pinned dependencies, compile the numba kernels once
#               (`stridelab warm-kernels`, into .venv/var/cache/stridelab-numba), run `stridelab demo`
#   make test   create .venv if missing, run the test suite
# Variables: PY=python3.11 (interpreter), ARGS="--no-serve" (demo options), PYTEST_ARGS="-m 'not slow'".

PY ?= python3
VENV := .venv
STAMP := $(VENV)/.installed-stamp
ARGS ?=
PYTEST_ARGS ?=

.PHONY: demo test install browser clean

$(STAMP): pyproject.toml requirements.lock
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
	$(VENV)/bin/python -m pip install --quiet --upgrade pip
	$(VENV)/bin/python -m pip install --quiet -r requirements.lock
	$(VENV)/bin/python -m pip install --quiet --no-deps -e .
	@echo "compiling the numba kernels once into the venv's shared cache (stridelab warm-kernels) …" >&2
	$(VENV)/bin/stridelab warm-kernels
	@touch $@

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/stridelab demo $(ARGS)

test: $(STAMP) browser
	$(VENV)/bin/python -m pytest $(PYTEST_ARGS)

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

clean:
	rm -rf $(VENV) stridelab-home .pytest_cache
