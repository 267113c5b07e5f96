# Two entry points for a fresh machine (see README):
#   make demo   set up .venv, preprocess a sample DEM, write a mesh and an offscreen view
#   make test   set up .venv and run the whole test suite
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint clean setup browser test-browser geoid

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,dev,bench]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/geoterrain preprocess sample_dems/fbm_513.tif -o out/fbm_513.geoterrain --overwrite
	$(BIN)/geoterrain info out/fbm_513.geoterrain
	$(BIN)/geoterrain mesh out/fbm_513.geoterrain -o out/fbm_513.ply --max-error 1
	$(BIN)/geoterrain render out/fbm_513.geoterrain -o out/fbm_513.png
	@echo "demo done: see out/"

test: $(STAMP)
	$(BIN)/python -m pytest -q

# The browser test (tests/export/test_cesium.py): Debian's chromium, Node/npm and the npm
# package cesium in .browser/ (needs root for apt-get, network for apt and npm).
browser:
	command -v chromium >/dev/null || apt-get install -y --no-install-recommends chromium
	command -v npm >/dev/null || apt-get install -y --no-install-recommends nodejs npm
	mkdir -p .browser && cd .browser && npm install --no-audit --no-fund cesium@1

# PROJ's EGM96 geoid grid (Debian's proj-data) for `geoterrain tiles --geoid egm96`.
geoid:
	test -e /usr/share/proj/egm96_15.gtx || apt-get install -y --no-install-recommends proj-data

test-browser: $(STAMP) browser
	$(BIN)/python -m pytest -q -m browser

lint: $(STAMP)
	$(BIN)/ruff check geoterrain cli tests benchmarks

clean:
	rm -rf $(VENV) out .pytest_cache
