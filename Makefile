# derive: the two set-up commands are `make generate` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: generate test bench venv clean system-deps embedded

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

generate: $(STAMP)
	$(PY) -m derive generate --out generated
	$(PY) -m derive simulate --out generated/glasgow_2link/sim --json generated/glasgow_2link/sim/metrics.json
	$(PY) -m derive simulate --controllers npid,dobc,npid_unprotected --voltage-limits 2,3 --duration 15 \
	    --out generated/glasgow_2link/sim/saturation

system-deps:
	bash scripts/install-system-deps.sh

# Cross-compile the controller with its self-test for Cortex-M4F (float) and
# Cortex-M3 (double, float), run both on QEMU, report size, stack, instructions.
embedded: $(STAMP) system-deps
	$(PY) -m derive embedded

test: $(STAMP) system-deps
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) -m benchmarks

clean:
	rm -rf $(VENV) build *.egg-info
