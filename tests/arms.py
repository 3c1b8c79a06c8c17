"""Arm descriptions built in code for the tests: planar chains of any length."""
from __future__ import annotations

from derive.model.examples import planar_chain as chain  # noqa: F401
from derive.model.examples import planar_chain_dict as chain_dict  # noqa: F401
