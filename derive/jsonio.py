"""Strict RFC 8259 JSON: the one way derive writes (and reads back) JSON.

Python's ``json`` writes NaN and Infinity as the bare words ``NaN`` and ``Infinity``,
which are not JSON (RFC 8259, section 6) and which strict parsers refuse. Here:

* :func:`dumps` writes with ``allow_nan=False``; a non-finite float raises
  ``ValueError`` naming where it is (``controllers.npid.links[0].rms_error``), never
  a silent ``NaN``;
* a figure that has no value is given as ``Undefined("why")``: ``"key": Undefined(...)``
  is written as ``"key": null`` and, beside it in the same object,
  ``"key_undefined": "why"``;
* ``digits`` writes every float at that many significant digits, so a committed file
  does not carry the last bits of one machine's CPU and libm;
* :func:`loads` parses strictly: NaN, Infinity and duplicate keys are errors.

Every JSON file derive writes goes through :func:`dumps` (tests/test_json.py checks
that no other module calls ``json.dump``/``json.dumps``).
"""
from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass
from typing import Any

UNDEFINED_SUFFIX = "_undefined"


@dataclass(frozen=True)
class Undefined:
    """A figure without a value, with the reason (written as null and ``<key>_undefined``)."""

    reason: str


def rounded(x: float, digits: int) -> float:
    """``x`` at ``digits`` significant digits (the nearest double of that decimal)."""
    return float(f"{x:.{digits - 1}e}")


def plain(value: Any, digits: int | None = None, where: str = "") -> Any:
    """``value`` as JSON data: dict (str keys), list, str, bool, None, int, finite float.

    Tuples become lists, numpy scalars and arrays Python numbers and lists; floats are
    rounded to ``digits`` significant digits when given. Raises ValueError, naming the
    place, for a non-finite float or an Undefined outside an object; TypeError for
    anything else.
    """
    if isinstance(value, dict):
        out: dict[str, Any] = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"{where or 'JSON'}: key {key!r} is not a string")
            if isinstance(item, Undefined):
                out[key] = None
                out[key + UNDEFINED_SUFFIX] = item.reason
            else:
                out[key] = plain(item, digits, f"{where}.{key}" if where else key)
        return out
    if isinstance(value, (list, tuple)) or type(value).__name__ == "ndarray":
        return [plain(item, digits, f"{where}[{i}]") for i, item in enumerate(list(value))]
    if isinstance(value, Undefined):
        raise ValueError(f"{where or 'JSON'}: an undefined figure needs a key, to put its reason beside it")
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        x = float(value)
        if not math.isfinite(x):
            raise ValueError(f"{where or 'JSON'}: {x} is not a JSON number (RFC 8259); "
                             "give an undefined figure as Undefined(reason)")
        return x if digits is None else rounded(x, digits)
    raise TypeError(f"{where or 'JSON'}: {type(value).__name__} is not JSON data")


def dumps(value: Any, *, digits: int | None = None, indent: int | None = 2, sort_keys: bool = True) -> str:
    """Strict JSON text of ``value`` (see :func:`plain`), ending in a newline."""
    return json.dumps(plain(value, digits), indent=indent, sort_keys=sort_keys, allow_nan=False,
                      ensure_ascii=True) + "\n"


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"not RFC 8259 JSON: {name}")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, item in pairs:
        if key in out:
            raise ValueError(f"not RFC 8259 interoperable JSON: the key {key!r} appears twice")
        out[key] = item
    return out


def loads(text: str | bytes) -> Any:
    """Parse strict JSON: NaN, Infinity and -Infinity (Python's extensions) and duplicate
    keys raise ValueError."""
    return json.loads(text, parse_constant=_refuse_constant, object_pairs_hook=_no_duplicates)
