# mrlib — two commands to know: `make demo` and `make test`.
# Both create the virtual environment (.venv) on first use.

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
READY := $(VENV)/.mrlib-ready

# Real motion capture (Bandai Namco Research Motion Dataset 1): read from $MRLIB_DATA_DIR
# (or ../shared/data/bandai-namco-motion-1) when present, else fetched on first use into
# mrlib's cache (`mrlib data fetch bandai`); the real-data tests skip without a local copy.
# Headless rendering (pyvista/VTK through EGL).
export PYVISTA_OFF_SCREEN ?= true
export PYVISTA_JUPYTER_BACKEND ?= static
export VTK_DEFAULT_OPENGL_WINDOW ?= vtkEGLRenderWindow

.PHONY: env demo test lint format lab notebooks bench clean blender-addon

$(READY): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e ".[dev]"
	$(BIN)/python -m ipykernel install --sys-prefix --name python3 --display-name "Python 3 (mrlib)" >/dev/null
	touch $(READY)

env: $(READY)

## End-to-end demo on data that ships with the repo; writes to outputs/ (replacing its last run).
demo: $(READY)
	$(BIN)/mrlib demo --out outputs --overwrite

## Lint, unit and real-data tests, and every notebook executed headless
## (smoke budget, models shared between notebooks through a fresh cache folder), on every
## core: one pytest-xdist worker per CPU, whole test files (or the notebooks) per worker.
TEST_JOBS ?= auto
test: $(READY)
	$(BIN)/ruff check mrlib tests bench tools blender conftest.py notebooks/conftest.py
	MRLIB_QUICK=1 MRLIB_CACHE_DIR=$${MRLIB_TEST_CACHE:-$$(mktemp -d)} $(BIN)/python -m pytest -n $(TEST_JOBS) --nbmake --nbmake-timeout=900 --durations=10 -p no:cacheprovider tests notebooks

lint: $(READY)
	$(BIN)/ruff check mrlib tests bench tools blender conftest.py notebooks/conftest.py
	$(BIN)/ruff format --check mrlib tests bench tools blender conftest.py notebooks/conftest.py

format: $(READY)
	$(BIN)/ruff format mrlib tests bench tools blender conftest.py notebooks/conftest.py
	$(BIN)/ruff check --fix mrlib tests bench tools blender conftest.py notebooks/conftest.py

## Execute every notebook in place at its default budget, so the committed files carry
## their figures (minutes each on 2 CPU cores; models are shared through mrlib's cache).
notebooks: $(READY)
	$(BIN)/python tools/run_notebooks.py

## JupyterLab on the notebooks, with live (trame) 3D views.
lab: $(READY)
	PYVISTA_JUPYTER_BACKEND=client $(BIN)/jupyter lab notebooks/

## Speed and memory benchmarks (print tables, write JSON to bench/results/).
bench: $(READY)
	$(BIN)/python bench/load_speed.py
	$(BIN)/python bench/metrics_speed.py
	$(BIN)/python bench/train_speed.py

## The Blender add-on (blender/mrlib_addon/) as the zip that Blender installs: writes
## dist/mrlib_addon.zip (standard library only, no .venv needed; docs/blender.md).
blender-addon:
	$(PYTHON) tools/make_blender_addon.py

clean:
	rm -rf $(VENV) outputs .pytest_cache
