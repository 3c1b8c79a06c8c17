"""Shared fixtures: derivations are computed once per session."""
from __future__ import annotations

import functools

import pytest

import derive
from derive.model.spec import packaged_arms
from tests import hypothesis_profiles  # noqa: F401 - loads the ci or fuzz profile before any test module


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
