# Two entry points for a fresh machine (see README):
#   make demo   set up .venv, preprocess a sample DEM, write a mesh and an offscreen view
#   make test   set up .venv and run the whole test suite (what CI runs; lists the 15 slowest)
# and for everyday work:
#   make test-fast           the fast tier (tests marked `fast`, and every doctest): about a
#                            minute on two cores, and it exercises every module
#   make test-fast-coverage  the fast tier, failing unless it exercised every module
#   make test-boundscheck    the fast tier and the grid-shape sweep with numba's bounds checks
#                            on (NUMBA_BOUNDSCHECK=1, kernels compiled into a cache of their own)
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-fast test-fast-coverage test-boundscheck lint clean setup browser test-browser geoid gdal

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,dev,bench,web]'
	touch $(STAMP)

setup: $(STAMP)

# The demo's commands compile the kernels they use on the first run (each says so, with a
# bar) and leave them cached: the map, the export and the GeoTIFF compile the rest that
# render, export and export-raster need, so a user's first commands start warm.
# Each command is a process of its own: the package's bytecode is written first (an
# editable install has none, and where PYTHONDONTWRITEBYTECODE is set each process would
# compile the sources it imports again; a no-op when up to date).
demo: $(STAMP)
	$(BIN)/python -m compileall -q geoterrain cli
	mkdir -p out
	$(BIN)/geoterrain preprocess sample_dems/fbm_513.tif -o out/fbm_513.geoterrain --overwrite
	$(BIN)/geoterrain info out/fbm_513.geoterrain
	$(BIN)/geoterrain mesh out/fbm_513.geoterrain -o out/fbm_513.ply --max-error 1 --overwrite
	$(BIN)/geoterrain render out/fbm_513.geoterrain -o out/fbm_513.png --overwrite
	$(BIN)/geoterrain render out/fbm_513.geoterrain -o out/fbm_513_map.png --map --overwrite \
		--water-level 300
	$(BIN)/geoterrain export out/fbm_513.geoterrain -o out/fbm_513.glb --max-error 5 \
		--print-size 150 --preview out/fbm_513_print.png --overwrite
	$(BIN)/geoterrain export-raster out/fbm_513.geoterrain --what hillshade \
		-o out/fbm_513_hillshade.tif --overwrite
	@echo "demo done: see out/"

# the whole suite on up to 4 worker processes; each test file stays on one worker, so its
# module fixtures (stores built once per file) are built once
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --maxprocesses 4 --dist loadfile --durations=40

FAST := -m 'fast and not slow and not browser'

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q $(FAST) --durations=10

test-fast-coverage: $(STAMP)
	$(BIN)/python -m pytest -q $(FAST) --durations=10 --tiercheck

# every compiled kernel the fast tier and the shape sweep reach, with bounds checks: an index
# outside an array is an IndexError, not a crash (tests/preprocessing/test_shape_sweep.py)
test-boundscheck: $(STAMP)
	NUMBA_BOUNDSCHECK=1 NUMBA_CACHE_DIR=.numba-boundscheck $(BIN)/python -m pytest -q \
		-m '(fast or boundscheck) and not slow and not browser' -p no:randomly

# The browser tests (tests/export/test_cesium.py, tests/serve/test_browser.py): Debian's
# chromium, Node/npm and the npm packages cesium, maplibre-gl and pmtiles in .browser/
# (needs root for apt-get, network for apt and npm). `geoterrain serve` finds them there.
browser:
	command -v chromium >/dev/null || apt-get install -y --no-install-recommends chromium
	command -v npm >/dev/null || apt-get install -y --no-install-recommends nodejs npm
	mkdir -p .browser && cd .browser && npm install --no-audit --no-fund cesium@1 \
		maplibre-gl@5 pmtiles@4

# PROJ's EGM96 geoid grid (Debian's proj-data) for `geoterrain tiles --geoid egm96`.
geoid:
	test -e /usr/share/proj/egm96_15.gtx || apt-get install -y --no-install-recommends proj-data

# GDAL's own tools (Debian's gdal-bin): gdaldem (hillshade, slope), gdal_viewshed and
# gdal_contour, the references the export and analysis tests compare with (they skip
# without them). Never fatal: without root or a package mirror the comparisons skip.
gdal:
	command -v gdal_viewshed >/dev/null && command -v gdaldem >/dev/null || \
		(apt-get update -qq && apt-get install -y -qq --no-install-recommends gdal-bin) || \
		echo "gdal-bin not installed: GDAL comparisons skip"

test-browser: $(STAMP) browser
	$(BIN)/python -m pytest -q -m browser

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) out .pytest_cache
