# derive: the two set-up commands are `make generate` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
# The exact versions derive is tested with (pyproject.toml states ranges): every install here uses them.
CONSTRAINTS := constraints.txt
# Wheels tests/test_wheel.py installs offline beside the wheel: an older numpy 2.x than the
# constraints' and the newest sympy published (scripts/wheelhouse.sh, from the package registry).
WHEELHOUSE := build/wheelhouse
WHEELHOUSE_STAMP := $(WHEELHOUSE)/.stamp

.PHONY: generate test fuzz bench corpus venv wheelhouse clean system-deps embedded docs

venv: $(STAMP)

$(STAMP): pyproject.toml $(CONSTRAINTS)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e '.[test]'
	touch $(STAMP)

# The docs extra (MkDocs, mkdocs-material, mkdocstrings) on top of the test environment, at the
# constraints' versions.
DOCS_STAMP := $(VENV)/.docs-stamp

$(DOCS_STAMP): $(STAMP) pyproject.toml $(CONSTRAINTS)
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e '.[test,docs]'
	touch $(DOCS_STAMP)

# The documentation site (mkdocs.yml, docs/) into build/site, warnings as errors. Its reference pages
# are generated from derive's parsers, key tables and generated headers, and every example on it is
# run or parse-checked (docs/hooks.py, docs/gen/).
# NO_MKDOCS_2_WARNING: mkdocs-material's notice about its successor, printed on every build, left out.
docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict --clean --site-dir build/site

wheelhouse: $(WHEELHOUSE_STAMP)

$(WHEELHOUSE_STAMP): scripts/wheelhouse.sh $(CONSTRAINTS) $(STAMP)
	bash scripts/wheelhouse.sh $(PY) $(WHEELHOUSE)
	touch $(WHEELHOUSE_STAMP)

generate: $(STAMP) $(WHEELHOUSE_STAMP)
	$(PY) -m derive generate --out generated
	$(PY) -m derive simulate --out generated/glasgow_2link/sim --json generated/glasgow_2link/sim/metrics.json
	$(PY) -m derive simulate --controllers npid,dobc,npid_unprotected --voltage-limits 2,3 --duration 15 \
	    --out generated/glasgow_2link/sim/saturation
	$(PY) -m derive sweep --out generated/glasgow_2link/sweep

system-deps:
	bash scripts/install-system-deps.sh

# Cross-compile the controller with its self-test for Cortex-M4F (float) and
# Cortex-M3 (double, float), run both on QEMU, report size, stack, instructions.
embedded: $(STAMP) system-deps
	$(PY) -m derive embedded

# Both cores of the CI machine (pytest-xdist); a module's tests stay on one worker so its
# module-scoped fixtures (a generated and compiled arm) are built once.
TEST_WORKERS ?= 2
# DERIVE_REQUIRE_PINNED: the constraints' versions are installed, so a test that compares bytes
# made under them (tests/test_generated.py) fails instead of skipping when they are not.
test: $(STAMP) $(WHEELHOUSE_STAMP) system-deps
	DERIVE_REQUIRE_PINNED=1 $(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=15

# The property tests (hypothesis) with FUZZ_FACTOR times the examples of `make test` and
# a new random seed each run (printed; `make fuzz SEED=n` repeats a run). `make test`
# runs the same tests derandomized (tests/hypothesis_profiles.py).
FUZZ_FACTOR ?= 20
ifndef SEED
SEED := $(shell od -An -N4 -tu4 /dev/urandom | tr -d ' ')
endif
FUZZ_TESTS ?= tests/test_spec_properties.py tests/test_hardening.py
fuzz: $(STAMP) $(WHEELHOUSE_STAMP) system-deps
	@echo "make fuzz: hypothesis seed $(SEED) (repeat with: make fuzz SEED=$(SEED))"
	DERIVE_REQUIRE_PINNED=1 DERIVE_HYPOTHESIS_PROFILE=fuzz DERIVE_FUZZ_FACTOR=$(FUZZ_FACTOR) \
	    $(PY) -m pytest -q -p no:cacheprovider --hypothesis-seed=$(SEED) $(FUZZ_TESTS)
	DERIVE_REQUIRE_PINNED=1 $(PY) -m pytest -q -p no:cacheprovider -m slow

# Every section of benchmarks/ (`python -m benchmarks`), printed as Markdown and recorded in
# docs/data/bench-run.json (strict JSON: each section's tables, notes, goals, date and versions).
# The documentation's benchmark tables are rendered from that file (<!-- bench-run: SECTION -->):
# committing it is what updates them. `$(PY) -m benchmarks --json docs/data/bench-run.json payload`
# re-runs one section and replaces only its record.
bench: $(STAMP)
	$(PY) -m benchmarks --json docs/data/bench-run.json

# Every arm of tests/data/urdf/corpus (vendor URDFs) through init, show, check, generate (C and
# Python self-tests), simulate and fmu --plant in a temporary folder, each command under
# CORPUS_TIMEOUT seconds (default 900); wall time and peak memory per arm and command go to
# build/corpus/corpus.md and corpus.json (benchmarks/corpus.py). `make corpus ARMS="ur3 ur10"`
# runs some arms only.
CORPUS_TIMEOUT ?= 900
corpus: $(STAMP) system-deps
	CORPUS_TIMEOUT=$(CORPUS_TIMEOUT) $(PY) -m benchmarks.corpus --out build/corpus $(ARMS)

clean:
	rm -rf $(VENV) build *.egg-info
