"""Shared fixtures: derivations are computed once per session."""
from __future__ import annotations

import functools

import pytest

import derive
from derive.model.spec import packaged_arms
from tests import hypothesis_profiles  # noqa: F401 - loads the ci or fuzz profile before any test module


@pytest.fixture(scope="session", autouse=True)
def _simulate_cache_in_a_temporary_folder(tmp_path_factory):
    """derive's caches (derive.cache: simulate's and show's) in a folder of this session, never the user's:
    the commands the tests run, in process or as subprocesses, inherit the variable."""
    import os

    from derive.cache import ENV

    old = os.environ.get(ENV)
    os.environ[ENV] = str(tmp_path_factory.mktemp("derive-cache"))
    yield
    os.environ.pop(ENV) if old is None else os.environ.__setitem__(ENV, old)


@functools.lru_cache(maxsize=None)
def derivation(name: str | None = None) -> derive.Derivation:
    """Derivation of a packaged arm (cached: derivations are pure)."""
    return derive.derive(derive.load_arm(name))


@pytest.fixture(scope="session")
def paper() -> derive.Derivation:
    """The default arm: the paper's two-link arm."""
    return derivation(None)


@pytest.fixture(params=packaged_arms())
def packaged(request) -> derive.Derivation:
    return derivation(request.param)
