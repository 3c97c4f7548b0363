# artic: two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
export PYTHONHASHSEED := 0

.PHONY: setup demo smoke test wheel-check test-slow bench lint clean

setup: $(STAMP)  ## create .venv and install artic with its dependencies

$(STAMP): pyproject.toml constraints.txt scripts/system-deps.sh
	./scripts/system-deps.sh
	@$(PYTHON) -c 'import sys; assert sys.version_info[:2] == (3, 11), "artic needs Python 3.11 (PyBullet wheels)"'
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -c constraints.txt -e '.[dev]'
	touch $(STAMP)

demo: setup  ## run the smoke pipeline on tiny defaults and show where its outputs are
	$(BIN)/artic pipeline smoke
	$(BIN)/artic infer-hierarchy artifacts/smoke/scans/storage_furniture/scans/000000_00_noisy.ply \
	  --segmenter artifacts/smoke/models/segmenter/storage_furniture/model.pt \
	  --labeller artifacts/smoke/models/hierarchy/storage_furniture/model.pt \
	  --out artifacts/smoke/hierarchy/000000_00
	@echo
	@echo "Outputs: artifacts/smoke/ (each folder has a manifest.json; see preview.png in the depth folders)"
	@find artifacts/smoke -maxdepth 4 -name preview.png -o -maxdepth 4 -name '*.png' -path '*reports*' | sort | sed 's/^/  /'
	@echo "  artifacts/smoke/hierarchy/000000_00/ (hierarchy.json, object.urdf, parts.ply, hierarchy.png)"

smoke: demo

test: setup  ## the wheel check, then the test suite (without slow tests)
	$(MAKE) --no-print-directory wheel-check
	$(BIN)/python -m pytest -n 2 -q

wheel-check: setup  ## build the wheel, install it in a fresh venv outside the checkout, run it there
	./scripts/wheel-check.sh $(PYTHON)

test-slow: setup
	$(BIN)/python -m pytest -n 2 -q -m slow

bench: setup  ## benchmarks; results in bench/results/ and docs/benchmarks.md
	$(BIN)/python bench/run_all.py

lint: setup
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench
	$(BIN)/mypy

clean:
	rm -rf artifacts/smoke .pytest_cache .mypy_cache .ruff_cache build dist
