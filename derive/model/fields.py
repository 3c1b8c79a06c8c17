"""Reading the values of an arm file: exact numbers, problems named by field.

A :class:`Reader` walks the parsed TOML and collects every problem as a
:class:`~derive.errors.Problem` (field path, expected, given); :func:`show`
renders a given value with its TOML kind (``string 'abc'``, ``boolean true``,
``array [1.0] (1 entry)``), escaped and bounded in length so that no value of a
file can flood or corrupt the one message. Numbers are exact Fractions of what
the file wrote and must be finite, nonzero-unless-zero doubles.
"""
from __future__ import annotations

import datetime
import math
import numbers
import re
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from derive.errors import Problem

MAX_TEXT = 200             # description, label: one line of a generated comment

_DECIMAL = r"\d{1,40}(?:\.\d{1,40})?(?:[eE][-+]?\d{1,3})?"  # bounded: no 10**(10**9)
FRACTION_STRING = re.compile(rf"\s*([-+]?)({_DECIMAL})\s*/\s*({_DECIMAL})\s*\Z")
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]{1,40}\Z")
_TRIGRAPH = re.compile(r"\?\?[=/'()!<>-]")
_ZERO = Fraction(0)


def printable(text: str) -> str:
    """``text``, escaped when it holds control or invisible characters."""
    return text if text.isprintable() else ascii(text)


def inline(value: Any, depth: int = 0) -> str:
    """A short TOML-like rendering of any value, bounded in depth and length."""
    if depth > 2:
        return "..."
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return repr(value) if len(value) <= 40 else f"{value[:40]!r}... ({len(value)} characters)"
    if isinstance(value, int) and value.bit_length() > 100:
        return f"<an integer of {int(value.bit_length() * math.log10(2)) + 1} digits>"
    if isinstance(value, (list, dict)):
        items = list(value.items() if isinstance(value, dict) else value)
        shown = [f"{key_text(x[0])} = {inline(x[1], depth + 1)}" if isinstance(value, dict)
                 else inline(x, depth + 1) for x in items[:6]] + (["..."] if len(items) > 6 else [])
        return ("{%s}" if isinstance(value, dict) else "[%s]") % ", ".join(shown)
    if isinstance(value, (datetime.date, datetime.time)):
        return value.isoformat()
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - any object in a caller's dict: shown by type only
        text = f"<{type(value).__name__}>"
    return text if len(text) <= 60 else text[:60] + "..."


def show(value: Any) -> str:
    """The given value as a message shows it, with its TOML kind unless a number."""
    text = inline(value)
    text = text if len(text) <= 100 else text[:100] + "..."
    if isinstance(value, list):
        return f"array {text} ({len(value)} entr{'y' if len(value) == 1 else 'ies'})"
    kinds = ((bool, "boolean "), (str, "string "), (dict, "table "),
             ((datetime.date, datetime.time), "date/time "), (type(None), "nothing: "))
    return next((kind for t, kind in kinds if isinstance(value, t)), "") + text


def key_text(key: Any) -> str:
    """A key as a field path shows it: bare when TOML allows, else quoted and escaped."""
    if isinstance(key, str) and _BARE_KEY.match(key):
        return key
    return ascii(key) if isinstance(key, str) and len(key) <= 40 else inline(key)


def path(field: str, key: Any) -> str:
    """The field path of ``key`` in the table at ``field`` ('' for the top level)."""
    return f"{field}.{key_text(key)}" if field else key_text(key)


def fmt(x: Fraction) -> str:
    """An exact number as a message shows it: an integer, or 6 significant digits."""
    return str(x.numerator) if x.denominator == 1 else f"{float(x):g}"


TEXT_RULE = (f"one line of printable text, at most {MAX_TEXT} characters, without '*/', '\"\"\"', "
              "'\\' or a '??' trigraph (it is copied into C comments and Python docstrings)")


def text_problem(text: str) -> str | None:
    """What keeps ``text`` out of a generated comment or docstring, or None."""
    bad = next((c for c in text if not c.isprintable()), None)
    if bad is not None:
        return f"contains {ascii(bad)}"
    if len(text) > MAX_TEXT:
        return f"{len(text)} characters"
    found = [s for s in ("*/", '"""', "\\") if s in text] + _TRIGRAPH.findall(text)
    return f"contains {found[0]!r}" if found else None


# -- numbers ------------------------------------------------------------------------------

def to_fraction(value: Any) -> Fraction | None:
    """Exact value of a TOML number or a 'p/q' string; None unless a finite double."""
    if isinstance(value, bool):
        return None
    if isinstance(value, numbers.Rational):
        x = Fraction(int(value.numerator), int(value.denominator))
    elif isinstance(value, numbers.Real):
        if not math.isfinite(f := float(value)):
            return None
        x = Fraction(repr(f))
    elif isinstance(value, str) and len(value) <= 100 and (m := FRACTION_STRING.match(value)):
        if (den := Fraction(m[3])) == 0:
            return None
        x = Fraction(m[2]) / den * (-1 if m[1] == "-" else 1)
    else:
        return None
    try:  # a finite double that is not 0 unless x is
        return x if x == 0 or (math.isfinite(f := float(x)) and f != 0) else None
    except OverflowError:
        return None


def _why_not_a_number(value: Any) -> str:
    """A hint after a rejected number's shown value ('' when the value says it all)."""
    if isinstance(value, float) and not math.isfinite(value):
        return " (not a number)" if math.isnan(value) else " (not finite; TOML reads 1e400 as inf)"
    if isinstance(value, str):
        m = FRACTION_STRING.match(value) if len(value) <= 100 else None
        if m:
            return " (division by zero)" if Fraction(m[3]) == 0 else " (beyond the range of a double)"
        if "/" in value:
            return " (not an exact fraction 'p/q' of decimals with exponents of at most 3 digits)"
        try:
            quoted = float(value)
        except ValueError:
            return ""
        if not math.isfinite(quoted):
            return " (not finite)"
        return " (a number in quotes: write it without quotes, or an exact fraction as 'p/q')"
    return " (beyond the range of a double)" if isinstance(value, numbers.Number) else ""


@dataclass(frozen=True)
class Num:
    """What a number field accepts: finite, optionally bounded below, in a unit."""

    unit: str = ""
    low: Fraction | None = None
    strict: bool = False
    alternative: str = ""

    @property
    def expected(self) -> str:
        bound = "" if self.low is None else f" {'>' if self.strict else '>='} {fmt(self.low)}"
        return f"a finite number{bound}" + (f" ({self.unit})" if self.unit else "") + self.alternative


def domain(num: Num) -> dict[str, bool]:
    """The SymPy assumptions of a symbol whose values ``num`` accepts: positive (> 0),
    nonnegative (>= 0) or real (unbounded). Every bound of an arm file is at 0. The symbol's
    domain is the value's range wherever it is checked again (derive.model.rules: the FMU's
    tunable parameters)."""
    if num.low is None:
        return {"real": True}
    if num.low != 0:
        raise ValueError(f"domain: a bound at 0 has a SymPy assumption, got {fmt(num.low)}")
    return {"positive": True} if num.strict else {"nonnegative": True}


POSITIVE = {u: Num(u, _ZERO, True) for u in ("m", "kg", "N m/A", "ohm", "s", "rad/s", "V", "")}
NONNEGATIVE = {u: Num(u, _ZERO) for u in ("kg", "kg m^2", "N m s/rad", "V s/rad", "m/s^2", "s")}
ANY = {u: Num(u) for u in ("m", "1/s", "")}


class Reader:
    """Collects problems while reading a nested mapping."""

    def __init__(self) -> None:
        self.problems: list[Problem] = []

    def add(self, field: str, expected: str, given: str) -> None:
        self.problems.append(Problem(field, expected, given))

    def bad(self, field: str, expected: str, value: Any) -> None:
        self.add(field, expected, show(value))

    def table(self, value: Any, field: str, keys: dict[str, str | None], what: str) -> dict | None:
        """``value`` as a table of ``keys`` (key -> expected text if required, else None)."""
        if not isinstance(value, dict):
            self.bad(field, what, value)
            return None
        for key in sorted(set(value) - set(keys), key=str):
            from difflib import get_close_matches   # only for an unknown key (difflib: ~3 ms to import)

            close = get_close_matches(key.lower(), list(keys), n=1) if isinstance(key, str) else []
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            self.add(path(field, key), f"one of the keys {', '.join(keys)}{hint}",
                     f"an unknown key set to {show(value[key])}")
        for key, expected in keys.items():
            if expected is not None and key not in value:
                self.add(path(field, key), expected, "nothing (the key is missing)")
        return value

    def value(self, value: Any, field: str, num: Num) -> Fraction | None:
        x = to_fraction(value)
        if x is None or (num.low is not None and (x < num.low or (num.strict and x == num.low))):
            self.add(field, num.expected, show(value) + (_why_not_a_number(value) if x is None else ""))
            return None
        return x

    def number(self, d: dict, key: str, field: str, num: Num,
               default: Fraction | None = None) -> Fraction | None:
        return self.value(d[key], path(field, key), num) if key in d else default

    def text(self, d: dict, key: str, field: str) -> str:
        value = d.get(key, "")
        why = text_problem(value) if isinstance(value, str) else "not a string"
        if why is not None:
            self.add(path(field, key), TEXT_RULE, f"{show(value)} ({why})")
            return ""
        return value
