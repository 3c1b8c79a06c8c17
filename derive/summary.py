"""Cheap, bounded ``repr`` for the derivation's dataclasses.

A dataclass's generated ``repr`` prints every field in full. For the symbolic stages
(Dynamics, Mpc, Observer, Npid, Derivation) that means printing whole SymPy matrices,
and printing an unevaluated ``W * Inverse(J)`` makes SymPy invert J symbolically: a
failing test's traceback (pytest formats the arguments of every frame) then ran for
hours. ``symbolic_repr`` names each field by its type and shape instead, in
constant time per field.
"""
from __future__ import annotations

import dataclasses


def describe(value: object) -> str:
    """A short description of one value: numbers and short strings as they are,
    matrices as ``Matrix(3x3)``, SymPy expressions and containers by type and size."""
    if value is None or isinstance(value, (bool, int, float)):
        return repr(value)
    if isinstance(value, str):
        return repr(value) if len(value) <= 40 else f"str({len(value)} chars)"
    shape = getattr(value, "shape", None)
    if isinstance(shape, tuple) and all(isinstance(s, int) for s in shape):
        return f"{type(value).__name__}({'x'.join(map(str, shape))})"
    if isinstance(value, (tuple, list, dict, set, frozenset)):
        return f"{type(value).__name__}(len {len(value)})"
    return type(value).__name__


def symbolic_repr(self: object) -> str:
    """``Class(field=description, ...)`` for a dataclass instance, never printing an expression."""
    fields = ", ".join(f"{f.name}={describe(getattr(self, f.name, None))}"
                       for f in dataclasses.fields(self) if f.repr)
    return f"{type(self).__name__}({fields})"


def compact_repr(cls: type) -> type:
    """Class decorator (above ``@dataclass``): give the class ``symbolic_repr``."""
    cls.__repr__ = symbolic_repr
    return cls
