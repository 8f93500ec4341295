# ReSTIR GI: environment, extension package, headless render, tests.
# Needs only Python 3.11 (with venv and pip), make and network access to PyPI.

PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.requirements-installed

BLEND ?= example_blends/room_animated.blend
# Extra arguments for tools/render.py, e.g. RENDER_ARGS="--frame 1 --samples 4".
RENDER_ARGS ?=

EXT_ID      := $(shell sed -n 's/^id *= *"\(.*\)"/\1/p' blender_manifest.toml)
EXT_VERSION := $(shell sed -n 's/^version *= *"\(.*\)"/\1/p' blender_manifest.toml)
ZIP         := dist/$(EXT_ID)-$(EXT_VERSION).zip
EXT_SOURCES := __init__.py blender_manifest.toml \
	$(shell find restir_addon core -type f -not -path '*/__pycache__/*' -not -name '*.pyc' 2>/dev/null)

# Keeps Blender away from the user's own configuration (~/.config/blender).
export BLENDER_USER_RESOURCES := $(CURDIR)/.blender_user

.PHONY: all venv build render test clean distclean

all: build

venv: $(STAMP)

$(STAMP): requirements.txt
	@command -v $(PYTHON) >/dev/null || { echo "error: $(PYTHON) not found (Python 3.11 is required by bpy 5.0.1)"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -r requirements.txt
	touch $@

build: $(ZIP)

$(ZIP): $(STAMP) tools/build_extension.py $(EXT_SOURCES)
	$(PY) tools/build_extension.py

render: $(STAMP) $(ZIP)
	$(PY) tools/render.py "$(BLEND)" $(RENDER_ARGS)

test: $(STAMP)
	$(PY) -m pytest -q tests

clean:
	rm -rf dist build out .blender_user .pytest_cache
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV) wheels
