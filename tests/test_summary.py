"""The derivation's dataclasses print in bounded time: a failing test's traceback
formats every frame's arguments with repr, and the default dataclass repr of an
Observer with L = W * Inverse(J) (n >= 3) made SymPy invert J symbolically (CI ran
for 54 minutes and was killed)."""
from __future__ import annotations

import pytest
import sympy as sp
from sympy.matrices.expressions.inverse import Inverse

from derive.control.pipeline import derive
from derive.model.spec import load_arm
from derive.summary import describe


def test_repr_of_a_three_joint_derivation_names_fields_without_expressions(monkeypatch):
    d = derive(load_arm("planar_3link"))
    assert isinstance(d.L, sp.MatMul)                      # the unevaluated W J^-1 (eq. 24, n >= 3)

    def refuse(self, **hints):
        raise AssertionError("repr evaluated Inverse(J)")

    monkeypatch.setattr(Inverse, "doit", refuse)
    with pytest.raises(AssertionError, match="evaluated"):
        str(-d.L)                                          # what the default repr did
    texts = [repr(x) for x in (d, d.dynamics, d.mpc, d.observer, d.npid)]
    assert all(len(t) < 2000 for t in texts)
    assert "L=MatMul(3x3)" in texts[0] and "L=MatMul(3x3)" in texts[3]
    assert texts[0].startswith("Derivation(")


def test_describe_gives_type_and_shape():
    assert describe(sp.zeros(2, 3)) == "MutableDenseMatrix(2x3)"
    assert describe((1, 2, 3)) == "tuple(len 3)"
    assert describe(1.5) == "1.5"
    assert describe("x" * 50) == "str(50 chars)"
