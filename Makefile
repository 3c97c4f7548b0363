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

demo: setup  ## the smoke pipeline, then the user's journeys on the shipped models
	$(BIN)/artic pipeline smoke
	$(BIN)/python scripts/demo.py --out artifacts/demo
	@echo
	@echo "Outputs: artifacts/smoke/ and artifacts/demo/ (each folder has a manifest.json)"
	@find artifacts/smoke artifacts/demo -maxdepth 4 -name preview.png -o -maxdepth 4 -name '*.png' -path '*reports*' -o -maxdepth 4 -name hierarchy.png | sort | sed 's/^/  /'

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
	$(BIN)/ruff check src tests bench scripts
	$(BIN)/ruff format --check src tests bench scripts
	$(BIN)/mypy

clean:
	rm -rf artifacts/smoke artifacts/demo .pytest_cache .mypy_cache .ruff_cache build dist
