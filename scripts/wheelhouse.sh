#!/usr/bin/env bash
# The wheels tests/test_wheel.py installs into a fresh virtual environment before derive's
# wheel, offline (pip --no-index): an older numpy 2.x than constraints.txt's (2.0.2, the lower
# bound pyproject.toml states) and the newest sympy published, so the test shows that
# installing derive keeps a user's numpy and sympy. Downloaded once from the package registry
# by `make wheelhouse` (a prerequisite of `make generate`, `make test` and `make fuzz`); the
# tests need no network. Usage: scripts/wheelhouse.sh PYTHON FOLDER
set -euo pipefail
python=${1:-.venv/bin/python}
dest=${2:-build/wheelhouse}
rm -rf "$dest.part"
mkdir -p "$dest.part"
"$python" -m pip download --quiet --disable-pip-version-check --no-deps --only-binary=:all: \
    --dest "$dest.part" "numpy==2.0.2" "sympy"
rm -rf "$dest"
mv "$dest.part" "$dest"
