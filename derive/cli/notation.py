"""Notation of ``derive show``: one name per symbol, in text (Unicode or ASCII) and LaTeX.

The derivation's symbols are ASCII identifiers shared with the generated code
(``dtheta1``, ``e0_1``); a reader sees the paper's notation instead: θ₁, θ̇₁, ÿd₁,
e₁(0), ė₁(0) in Unicode, ``theta1``, ``dtheta1``, ``e1(0)``, ``de1(0)`` in ASCII
and ``\\dot{\\theta}_{1}``, ``\\dot{e}_{1}(0)`` in LaTeX. Names come from the
roles of :class:`derive.model.symbols.JointSymbols`, never from parsing printed
text. The printers are SymPy printer subclasses; :func:`wrap` lays a sum out on
lines of at most a given width, breaking between terms.
"""
from __future__ import annotations

import unicodedata
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import sympy as sp
from sympy.printing.latex import LatexPrinter
from sympy.printing.precedence import PRECEDENCE
from sympy.printing.str import StrPrinter

SUB = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")
SUP = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")
DOT, DDOT = "\u0307", "\u0308"      # combining dot and diaeresis above

# role of a JointSymbols field -> (Unicode base, ASCII pattern, LaTeX pattern); {i} is the joint number
ROLES: Mapping[str, tuple[str, str, str]] = {
    "theta": ("θ{i}", "theta{i}", r"\theta_{{{i}}}"),
    "dtheta": ("θ" + DOT + "{i}", "dtheta{i}", r"\dot{{\theta}}_{{{i}}}"),
    "ddtheta": ("θ" + DDOT + "{i}", "ddtheta{i}", r"\ddot{{\theta}}_{{{i}}}"),
    "yd": ("yd{i}", "yd{i}", r"y_{{d,{i}}}"),
    "dyd": ("ẏd{i}", "dyd{i}", r"\dot{{y}}_{{d,{i}}}"),
    "ddyd": ("ÿd{i}", "ddyd{i}", r"\ddot{{y}}_{{d,{i}}}"),
    "int_e": ("∫e{i}", "int_e{i}", r"\textstyle\int_0^t e_{{{i}}}"),
    "u": ("u{i}", "u{i}", r"u_{{{i}}}"),
    "z": ("z{i}", "z{i}", r"z_{{{i}}}"),
    "e": ("e{i}", "e{i}", r"e_{{{i}}}"),
    "de": ("ė{i}", "de{i}", r"\dot{{e}}_{{{i}}}"),
    "e0": ("e{i}(0)", "e{i}(0)", r"e_{{{i}}}(0)"),
    "de0": ("ė{i}(0)", "de{i}(0)", r"\dot{{e}}_{{{i}}}(0)"),
}


@dataclass(frozen=True)
class Names:
    """Display names of symbols, per style: ``text`` (Unicode), ``ascii``, ``latex``."""

    text: Mapping[sp.Symbol, str]
    ascii: Mapping[sp.Symbol, str]
    latex: Mapping[sp.Symbol, str]

    @staticmethod
    def of(joint_symbols: object, extra: Sequence[sp.Symbol] = ()) -> "Names":
        """Names for every role of a JointSymbols, and ``extra`` symbols such as T1, T2
        (a trailing number becomes a subscript)."""
        text, ascii_, latex = {}, {}, {}
        for f in fields(joint_symbols):
            uni, asc, tex = ROLES[f.name]
            for k, s in enumerate(getattr(joint_symbols, f.name), start=1):
                text[s] = uni.format(i=str(k).translate(SUB))
                ascii_[s] = asc.format(i=k)
                latex[s] = tex.format(i=k)
        for s in extra:
            stem = s.name.rstrip("0123456789")
            digits = s.name[len(stem):]
            text[s] = stem + digits.translate(SUB)
            ascii_[s] = s.name
            latex[s] = f"{stem}_{{{digits}}}" if digits else stem
        return Names(text, ascii_, latex)


def width(text: str) -> int:
    """Columns ``text`` takes on a terminal (combining marks take none; an ASCII text has none)."""
    if text.isascii():
        return len(text)
    return sum(0 if unicodedata.combining(ch) else 1 for ch in text)


def subscript(name: str, index: Sequence[int], unicode: bool) -> str:
    """J₁₂ (J₁,₁₀ from ten joints on), or J[1,2] in ASCII."""
    if not unicode:
        return f"{name}[{','.join(map(str, index))}]"
    sep = "," if any(i > 9 for i in index) else ""
    return name + sep.join(str(i).translate(SUB) for i in index)


class TextPrinter(StrPrinter):
    """One-line text: the display names, ``·`` between factors and superscript powers
    (Unicode) or ``*`` and ``^`` (ASCII), floats with ``digits`` significant digits,
    exact fractions in parentheses where they multiply."""

    def __init__(self, names: Mapping[sp.Symbol, str], unicode: bool, digits: int = 6) -> None:
        super().__init__({"order": None})
        self._names, self._unicode, self._digits = names, unicode, digits

    def _print_Symbol(self, expr: sp.Symbol) -> str:
        return self._names.get(expr, expr.name)

    def _print_Float(self, expr: sp.Float) -> str:
        return f"{float(expr):.{self._digits}g}"

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        base, exp = expr.as_base_exp()
        if exp.is_Integer and exp > 1:
            b = self.parenthesize(base, PRECEDENCE["Pow"], strict=True)
            return b + str(exp).translate(SUP) if self._unicode else f"{b}^{exp}"
        if exp == -1:
            return "1/" + self.parenthesize(base, PRECEDENCE["Pow"], strict=True)
        return super()._print_Pow(expr, rational)

    def _print_Mul(self, expr: sp.Mul) -> str:
        c, rest = expr.as_coeff_Mul()
        sign, c = ("-", -c) if c.is_negative else ("", c)
        num, den = [], []
        for f in sorted(sp.Mul.make_args(rest), key=lambda f: (not f.is_Symbol and not f.is_Pow,
                                                             sp.default_sort_key(f.as_base_exp()[0]))):
            b, e = f.as_base_exp()
            (den if e.is_Number and e.is_negative else num).append(b ** -e if e.is_Number and e.is_negative else f)
        parts = []
        if c != 1 or not num:
            text = self._print(c)
            parts.append(f"({text})" if num and c.is_Rational and not c.is_Integer else text)
        parts += [self.parenthesize(f, PRECEDENCE["Mul"], strict=False) for f in num]
        out = ("·" if self._unicode else "*").join(parts)
        if den:
            d = ("·" if self._unicode else "*").join(self.parenthesize(f, PRECEDENCE["Mul"], strict=False) for f in den)
            out += "/" + (f"({d})" if len(den) > 1 else d)
        return sign + out

    def _print_Add(self, expr: sp.Add, order: str | None = None) -> str:
        return " ".join(self.terms(expr))

    def _print_Infinity(self, expr: sp.Expr) -> str:
        return "∞" if self._unicode else "inf"

    def terms(self, expr: sp.Expr) -> list[str]:
        """The terms of a sum, each with its sign ("+ a", "- b"; the first without "+"),
        a constant first, the rest in SymPy's canonical order."""
        ordered = self._as_ordered_terms(expr, order=None) if expr.is_Add else [expr]
        ordered = sorted(ordered, key=lambda t: not t.is_number)  # stable: constant first
        out = []
        for k, term in enumerate(ordered):
            text = self._print(term)
            negative = text.startswith("-")
            body = text[1:] if negative else text
            if k == 0:
                out.append(text)
            else:
                out.append(("- " if negative else "+ ") + body)
        return out


def wrap(lhs: str, terms: Sequence[str], limit: int, indent: str = "  ") -> list[str]:
    """``lhs = t1 + t2 ...`` on lines of at most ``limit`` columns, breaking before a
    term's sign; continuation lines align under the first term. A single term wider
    than the line stays whole (nothing is cut)."""
    head = f"{indent}{lhs} = "
    pad = " " * width(head)
    lines, line = [], head
    for k, term in enumerate(terms):
        piece = term if k == 0 else " " + term
        if k > 0 and width(line) + width(piece) > limit:
            lines.append(line)
            line = pad + term
        else:
            line += piece
    lines.append(line)
    return lines


class TexPrinter(LatexPrinter):
    """LaTeX with the display names and ``digits`` significant digits."""

    def __init__(self, names: Mapping[sp.Symbol, str], digits: int = 6) -> None:
        super().__init__({"mat_str": "bmatrix", "mat_delim": "", "symbol_names": dict(names)})
        self._digits = digits

    def _print_Float(self, expr: sp.Float) -> str:
        mantissa, _, exponent = f"{float(expr):.{self._digits}g}".partition("e")
        return mantissa + (rf" \cdot 10^{{{int(exponent)}}}" if exponent else "")
