# ReSTIR GI: environment, extension packages, headless render, tests.
# Needs make, network access to PyPI and Python 3.13 (with venv and pip; found
# through pyenv, on PATH or given as PYTHON313=...), or Python 3.11 for the
# 3.11 line.
#
# Two lines of Blender, each with its own environment (LINE=...):
#   py313 (default)  bpy 5.2.3, Python 3.13, numpy 2.x: Blender 5.1 / 5.2 LTS
#                    .venv, requirements.txt
#   py311            bpy 5.0.1, Python 3.11, numpy 1.26: Blender 4.2 LTS to 5.0
#                    .venv-py311, requirements-py311.txt
# e.g. `make test` (whole suite, current LTS), `make test-fast` (without
# the tests marked slow), `make LINE=py311 test`,
# `make test-py311` (the 3.11 line's packaging, install and render tests,
# `make LINE=py311 test-subset`), `make lint` (ruff, configured in
# pyproject.toml; installed into the environment when missing).

LINE ?= py313
ifeq ($(LINE),py313)
PYVER        := 3.13
VENV         := .venv
REQUIREMENTS := requirements.txt
USER_DIR     := .blender_user
else ifeq ($(LINE),py311)
PYVER        := 3.11
VENV         := .venv-py311
REQUIREMENTS := requirements-py311.txt
USER_DIR     := .blender_user-py311
else
$(error LINE must be py313 (the default) or py311, not "$(LINE)")
endif

# An interpreter to make the environment with, e.g. PYTHON313=/opt/python/bin/python3.13
# (default: tools/find_python.sh looks for one).
PYTHON_GIVEN := $(PYTHON$(subst .,,$(PYVER)))
PY    := $(VENV)/bin/python
STAMP := $(VENV)/.requirements-installed

BLEND ?= example_blends/room_animated.blend
# Extra arguments for tools/render.py, e.g. RENDER_ARGS="--frame 1 --samples 4".
RENDER_ARGS ?=
# Extra arguments for pytest, e.g. PYTEST_ARGS="-x -k farm".
PYTEST_ARGS ?=

# The packaging, install and render tests with ReSTIR animations: the
# packages built, validated, installed and rendered with (tools/render.py),
# the engine's final renders and animations, chunk warm-ups, tools/farm.py's
# chunks. CI runs them on the 3.11 line (the whole suite on the current one).
SUBSET_TESTS := tests/addon/test_extension.py tests/addon/test_addon_render.py tests/addon/test_addon_animation.py \
	tests/addon/test_addon_chunks.py \
	tests/tools/test_farm.py

EXT_ID      := $(shell sed -n 's/^id *= *"\(.*\)"/\1/p' blender_manifest.toml)
EXT_VERSION := $(shell sed -n 's/^version *= *"\(.*\)"/\1/p' blender_manifest.toml)
# The package for this machine's platform (tools/build_extension.py copies it
# from dist/$(EXT_ID)-$(EXT_VERSION)-<platform>.zip, one of which is built per platform).
ZIP         := dist/$(EXT_ID)-$(EXT_VERSION).zip
EXT_SOURCES := __init__.py blender_manifest.toml \
	$(shell find restir_addon core -type f -not -path '*/__pycache__/*' -not -name '*.pyc' 2>/dev/null)

# Keeps Blender away from the user's own configuration (~/.config/blender).
export BLENDER_USER_RESOURCES := $(CURDIR)/$(USER_DIR)

.PHONY: all venv build render test test-fast test-subset test-py311 e2e lint clean distclean

all: build

venv: $(STAMP)

# A $(VENV) of another Python (e.g. a .venv of the 3.11 days) is made anew.
$(STAMP): $(REQUIREMENTS) tools/find_python.sh
	@python=$$(sh tools/find_python.sh $(PYVER) "$(PYTHON_GIVEN)") || exit 1; \
	if [ -e $(VENV) ] && [ "$$($(PY) -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)" != "$(PYVER)" ]; then \
		echo "$(VENV) is not a Python $(PYVER) environment: making it anew"; rm -rf $(VENV); \
	fi; \
	echo "$$python -m venv $(VENV)"; \
	"$$python" -m venv $(VENV)
	$(PY) -m pip install -r $(REQUIREMENTS)
	touch $@

build: $(ZIP)

$(ZIP): $(STAMP) tools/build_extension.py $(EXT_SOURCES)
	$(PY) tools/build_extension.py

render: $(STAMP) $(ZIP)
	$(PY) tools/render.py "$(BLEND)" --user-resources "$(USER_DIR)" $(RENDER_ARGS)

test: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_ARGS) tests

# The loop to run after each edit: unit and statistical tests without the
# ones marked slow (the Cycles comparisons, whole-animation and packaging
# tests, the heaviest statistical ones).
test-fast: $(STAMP)
	$(PY) -m pytest -q -m "not slow" $(PYTEST_ARGS) tests

test-subset: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_ARGS) $(SUBSET_TESTS)

test-py311:
	$(MAKE) LINE=py311 test-subset

# The extension in a real Blender 5.2 window (tests/e2e/): needs the Debian
# root that tools/real_blender_setup.sh builds (and root privileges); the
# test skips with the reason where it is missing. Screenshots: bench/out/e2e/.
e2e: $(STAMP) $(ZIP)
	$(PY) -m pytest -q -rs $(PYTEST_ARGS) tests/e2e

# ruff, pinned to one minor version: installed into $(VENV) when missing or
# of another version.
RUFF_MINOR := 0.17

lint: $(STAMP)
	@$(PY) -m ruff --version 2>/dev/null | grep -q '^ruff $(subst .,\.,$(RUFF_MINOR))\.' || \
		$(PY) -m pip install "ruff==$(RUFF_MINOR).*"
	$(PY) -m ruff check .

clean:
	rm -rf dist build out .blender_user .blender_user-py311 .pytest_cache
	find . \( -path ./.venv -o -path ./.venv-py311 \) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf .venv .venv-py311 wheels
