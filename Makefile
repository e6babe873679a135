# treeform: `make demo` (venv + install + reconstruct the bundled sample), `make test`, `make bench`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
VALIDATOR := tools/node_modules/gltf-validator/package.json

.PHONY: demo test bench sysdeps validator clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[test]"
	touch $(STAMP)

sysdeps:
	@bash scripts/ensure_sysdeps.sh

# the Khronos glTF validator (npm) used by the export tests; skipped quietly without node/npm
validator:
	@if command -v npm >/dev/null 2>&1; then \
	  [ -f $(VALIDATOR) ] || npm ci --prefix tools --no-audit --no-fund --loglevel=error; \
	else echo "npm not found: the glTF validator test will be skipped"; fi

demo: $(STAMP) sysdeps
	$(VENV)/bin/treeform demo --out out/demo

test: $(STAMP) sysdeps validator
	$(PY) -m pytest -q -n 2 --dist loadfile

bench: $(STAMP) sysdeps
	$(PY) benchmarks/run.py
	$(PY) benchmarks/bench_growth.py
	$(PY) benchmarks/bench_variations.py
	$(PY) benchmarks/bench_bimodal.py
	$(PY) benchmarks/bench_dataset.py
	$(PY) benchmarks/bench_cloud.py

clean:
	rm -rf out .pytest_cache
