# dftl-warp: `make demo` and `make test` set everything up on a fresh machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test install bench clean

# setuptools warns about any editable install whose package maps a folder elsewhere (kernels/ is
# installed as dftl_warp.kernels): nothing to act on, so that warning is not shown
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	PYTHONWARNINGS="ignore:Editable installation" $(BIN)/python -m pip install -q -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/dftl-warp simulate scenes/default.usda -o out/demo.usdc
	$(BIN)/dftl-warp render out/demo.usdc --frame 30 --resolution 960x720 --spp 4 -o out/demo.png

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python scripts/bench.py --device cpu

clean:
	rm -rf $(VENV) out build *.egg-info
