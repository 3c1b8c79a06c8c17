"""Hypothesis profiles of the suite: ``ci`` (the default: ``make test`` and CI) and
``fuzz`` (``make fuzz``).

* ``ci``: derandomized (each test's examples are a fixed function of the test), no
  example database and no deadline, so every run on every machine draws the same
  examples and a fresh clone passes or fails exactly as this one.
* ``fuzz``: random (a new seed each run unless ``--hypothesis-seed`` is given; the
  Makefile prints the one it uses), still no database, and :func:`examples` scales
  every test's count by ``DERIVE_FUZZ_FACTOR`` (default 20).

The profile is chosen by the environment variable ``DERIVE_HYPOTHESIS_PROFILE``
(``ci`` when unset) and loaded by ``tests/conftest.py`` before any test module is
imported, so module-level ``settings(...)`` inherit it.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, settings
from hypothesis.configuration import set_hypothesis_home_dir

PROFILE = os.environ.get("DERIVE_HYPOTHESIS_PROFILE", "ci")
FACTOR = int(os.environ.get("DERIVE_FUZZ_FACTOR", "20")) if PROFILE == "fuzz" else 1

# No .hypothesis folder in the working tree: hypothesis' caches go to the temp dir.
set_hypothesis_home_dir(Path(tempfile.gettempdir()) / "derive-hypothesis")
_COMMON = dict(database=None, deadline=None, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.differing_executors])
settings.register_profile("ci", derandomize=True, **_COMMON)
settings.register_profile("fuzz", derandomize=False, **_COMMON)
if PROFILE not in ("ci", "fuzz"):
    raise ValueError(f"DERIVE_HYPOTHESIS_PROFILE: expected 'ci' or 'fuzz', got {PROFILE!r}")
settings.load_profile(PROFILE)


def examples(n: int) -> int:
    """The number of examples of a test that draws ``n`` under the ``ci`` profile."""
    return n * FACTOR
