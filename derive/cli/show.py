"""``derive show``: the Derivation as readable text or LaTeX."""
from __future__ import annotations

import sympy as sp

from derive.control.pipeline import Derivation


def _entries(d: Derivation) -> list[tuple[str, str, object]]:
    """(name, paper reference, expression) in reading order."""
    k1, k2 = (sp.factor(k) for k in d.k_formulas)
    out = [
        ("J(theta)", "eq. 12, a6", d.J), ("G(theta, dtheta)", "eq. 12", d.G), ("B", "eq. 12", d.B),
        ("C", "eq. 13", d.C),
        ("k1(T1, T2)", "eq. 16, 18", k1), ("k2(T1, T2)", "eq. 17, 18", k2),
        ("K1", "eq. 16", d.K1), ("K2", "eq. 17", d.K2),
        ("W", "eq. 25", d.W), ("p(dtheta)", "eq. 23", d.numeric(d.observer.p)),
    ]
    if d.n <= 2:
        out.append(("L(theta)", "eq. 24", d.L))
    out += [("P(theta)", "eq. 35", d.P), ("D(theta)", "eq. 36", d.D), ("I", "eq. 37", d.I),
            ("N(theta, dtheta)", "eq. 38", d.N), ("dhat(0)", "eq. 30, derived (not eq. 31)", d.dhat0)]
    if d.lumped is not None:
        out += [(k, "eq. a6", v) for k, v in d.lumped.items()]
        out.append(("max |dtheta2| for (26)", "eq. 26: w1 / X", d.speed_bound))
    return out


def _tidy(expr, exact: bool, n: int):
    """Readable form: per entry expand and (small arms) trigsimp; 6 digits unless exact.

    Display only: the derivation itself is never simplified as a whole.
    """
    if isinstance(expr, sp.MatrixBase):
        expr = expr.applyfunc(lambda x: sp.trigsimp(sp.expand(x)) if n <= 3 else x)
    if exact or not expr.has(sp.Rational) or {str(x) for x in expr.free_symbols} & {"T1", "T2"}:
        return expr
    return sp.N(expr, 6)


def render_text(d: Derivation, exact: bool = False, unicode: bool = True) -> str:
    """Plain-text (pretty-printed) view of every attribute of the derivation."""
    arm = d.arm
    lines = [f"arm {arm.name}: {arm.n} joint{'s' if arm.n > 1 else ''}, {arm.description}".rstrip(", "),
             f"source: {arm.source}", ""]
    for name, ref, expr in _entries(d):
        lines.append(f"{name}   ({ref})")
        lines.append(sp.pretty(_tidy(expr, exact, d.n), use_unicode=unicode, wrap_line=False))
        lines.append("")
    return "\n".join(lines)


def render_latex(d: Derivation, exact: bool = False) -> str:
    """LaTeX (one display equation per attribute) of the derivation."""
    lines = [f"% derive show --latex {d.arm.name}"]
    for name, ref, expr in _entries(d):
        lines.append(f"% {name} ({ref})")
        lines.append(r"\[ " + sp.latex(_tidy(expr, exact, d.n)) + r" \]")
    return "\n".join(lines) + "\n"


def add_arguments(parser) -> None:
    """CLI: derive show [ARM] [--latex] [--exact]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    parser.add_argument("--exact", action="store_true", help="exact rationals instead of 6 digits")


def run(args) -> int:
    import sys

    from derive.control.pipeline import derive
    from derive.model.spec import load_arm

    from derive.cli import report_warnings

    d = derive(load_arm(args.arm))
    report_warnings(d)
    if args.latex:
        text = render_latex(d, exact=args.exact)
    else:
        encoding = (getattr(sys.stdout, "encoding", None) or "").lower()
        text = render_text(d, exact=args.exact, unicode=encoding.startswith("utf"))
    sys.stdout.write(text if text.endswith("\n") else text + "\n")
    return 0
