"""SI unit strings of derive (``kg m^2``, ``N m/A``, ``1/s``) as FMI units.

An FMI ``<Unit>`` has a name and its exponents of the SI base units
(``<BaseUnit kg="1" m="2"/>``, FMI 2.0 section 2.2.2, FMI 3.0 section 2.4.3).
Names follow the Modelica convention every FMI importer reads (``kg.m2``,
``N.m/A``, ``m/s2``, ``Ohm``). A symbol this module does not know keeps its
name and gets no base units (allowed by the standard), never a wrong one.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")  # FMI's order of BaseUnit attributes

# symbol -> (Modelica name, exponents of the base units)
_SYMBOLS: dict[str, tuple[str, dict[str, int]]] = {
    "1": ("1", {}), "m": ("m", {"m": 1}), "kg": ("kg", {"kg": 1}), "s": ("s", {"s": 1}),
    "A": ("A", {"A": 1}), "rad": ("rad", {"rad": 1}), "N": ("N", {"kg": 1, "m": 1, "s": -2}),
    "V": ("V", {"kg": 1, "m": 2, "s": -3, "A": -1}), "ohm": ("Ohm", {"kg": 1, "m": 2, "s": -3, "A": -2}),
}
_TERM = re.compile(r"([A-Za-z]+|1)(?:\^(-?\d+))?\Z")


@dataclass(frozen=True)
class Unit:
    """An FMI unit: its name and the nonzero base-unit exponents in FMI's order
    (empty when the unit is not known here)."""

    name: str
    base: tuple[tuple[str, int], ...]
    known: bool


def _side(text: str) -> list[tuple[str, int]] | None:
    terms = []
    for word in text.split():
        match = _TERM.match(word)
        if match is None or match.group(1) not in _SYMBOLS:
            return None
        terms.append((match.group(1), int(match.group(2) or 1)))
    return terms


def _name(terms: list[tuple[str, int]]) -> str:
    return ".".join(_SYMBOLS[s][0] + (str(p) if p != 1 else "") for s, p in terms) or "1"


def fmi_unit(text: str) -> Unit | None:
    """The FMI unit of a derive unit string; None for a dimensionless quantity ("").

    ``"kg m^2"`` -> ``kg.m2`` (kg 1, m 2); ``"V s/rad"`` -> ``V.s/rad``;
    ``"1/s"`` -> ``1/s`` (s -1). One ``/`` at most: all after it is the denominator.
    """
    text = text.strip()
    if not text:
        return None
    num_text, _, den_text = text.partition("/")
    num, den = _side(num_text), _side(den_text) if den_text else []
    if num is None or den is None or not num:
        plain = re.sub(r"[^A-Za-z0-9./]", ".", text)
        return Unit(plain, (), False)
    exponents = dict.fromkeys(BASE, 0)
    for terms, sign in ((num, 1), (den, -1)):
        for symbol, power in terms:
            for base, e in _SYMBOLS[symbol][1].items():
                exponents[base] += sign * power * e
    name = _name(num) + (f"/{_name(den)}" if den else "")
    return Unit(name, tuple((b, e) for b, e in exponents.items() if e), True)
