"""``derive show``: the Derivation as readable text or LaTeX.

Text fits ``WIDTH`` (100) columns: a matrix whose grid fits is printed as a grid,
any other is listed entry by entry (J₁₂ = ...), sums wrapped between terms. The
entries are shown in a normal form (:func:`derive.dynamics.identities.fourier_form`:
products of sines and cosines as sines and cosines of sums, expanded), never
simplified as whole matrices; 6 significant digits unless ``--exact``. Names are
the paper's (θ̇, ÿd, ė(0), :mod:`derive.cli.notation`); LaTeX gives each quantity
one labelled display equation.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.cli.notation import Names, TexPrinter, TextPrinter, subscript, width, wrap
from derive.control.pipeline import Derivation
from derive.dynamics.identities import fourier_form
from derive.dynamics.trigpoly import constant_angles
from derive.model.actuators import input_word, units_text
from derive.model.spec import gain_units_text

WIDTH = 100
DIGITS = 6


@dataclass(frozen=True)
class Entry:
    """One quantity of the derivation: ``key`` (ASCII, also the LaTeX label), its name as
    text / ASCII / LaTeX, the base name of its elements (J for J₁₂), what it is, the
    paper's reference and the value (a SymPy expression or matrix)."""

    key: str
    text: str
    ascii: str
    latex: str
    element: tuple[str, str, str]
    what: str
    ref: str
    value: object
    formula: bool = False      # shown exact and as it is (k1, k2 in T1, T2)


def _b_what(d: Derivation) -> str:
    """What B maps: joint torque per volt (DC motors), per motor torque (torque actuation: the gear ratio)."""
    per = {"V": "volt", "N m": "N m of motor torque (the gear ratio)", "N": "N of motor force (the gear ratio)"}
    units = list(dict.fromkeys(d.arm.input_units))
    return "input matrix, joint torque per " + (per[units[0]] if len(units) == 1 else "unit of u (V or N m per motor)")


def entries(d: Derivation) -> list[Entry]:
    """Every quantity shown, in reading order."""
    k1, k2 = (sp.factor(k) for k in d.k_formulas)
    E = Entry
    out = [
        E("J", "J(θ)", "J(theta)", r"J(\theta)", ("J", "J", "J"), "inertia matrix", "eq. 12, a6", d.J),
        E("G", "G(θ, θ̇)", "G(theta, dtheta)", r"G(\theta, \dot{\theta})", ("G", "G", "G"),
          "Coriolis, centrifugal, gravity and damping torques", "eq. 12", d.G),
        E("B", "B", "B", "B", ("B", "B", "B"), _b_what(d), "eq. 12", d.B),
        E("C", "C", "C", "C", ("C", "C", "C"), "output matrix, y = C theta", "eq. 13", d.C),
        E("k1", "k1(T₁, T₂)", "k1(T1, T2)", "k_1(T_1, T_2)", ("k1", "k1", "k_1"), "gain formula", "eq. 16, 18",
          k1, formula=True),
        E("k2", "k2(T₁, T₂)", "k2(T1, T2)", "k_2(T_1, T_2)", ("k2", "k2", "k_2"), "gain formula", "eq. 17, 18",
          k2, formula=True),
        E("K1", "K1", "K1", "K_1", ("K1", "K1", "K_1"), "predictive gain on e", "eq. 16", d.K1),
        E("K2", "K2", "K2", "K_2", ("K2", "K2", "K_2"), "predictive gain on de/dt", "eq. 17", d.K2),
        E("W", "W", "W", "W", ("W", "W", "W"), f"observer gain [{gain_units_text(d.arm.prismatic)}]", "eq. 25", d.W),
        E("p", "p(θ̇)", "p(dtheta)", r"p(\dot{\theta})", ("p", "p", "p"), "observer function", "eq. 23",
          d.numeric(d.observer.p)),
    ]
    if d.n <= 2:
        out.append(E("L", "L(θ)", "L(theta)", r"L(\theta)", ("L", "L", "L"), "observer gain W J^-1 [1/s]", "eq. 24", d.L))
    out += [
        E("P", "P(θ)", "P(theta)", r"P(\theta)", ("P", "P", "P"), "proportional gain", "eq. 35", d.P),
        E("D", "D(θ)", "D(theta)", r"D(\theta)", ("D", "D", "D"), "derivative gain", "eq. 36", d.D),
        E("I", "I", "I", "I", ("I", "I", "I"), "integral gain", "eq. 37", d.I),
        E("N", "N(θ, θ̇)", "N(theta, dtheta)", r"N(\theta, \dot{\theta})", ("N", "N", "N"),
          "nonlinear term", "eq. 38", d.N),
        E("dhat0", "d̂(0)", "dhat(0)", r"\hat{d}(0)", ("d̂", "dhat", r"\hat{d}"),
          "initial disturbance estimate", "eq. 30; derived, not the printed eq. 31", d.dhat0),
    ]
    if d.lumped is not None:
        out += [E(k, k, k, k if k == "X" else f"{k[0]}_{k[1]}", (k, k, k), "lumped inertia parameter", "eq. a6", v)
                for k, v in d.lumped.items()]
        out.append(E("speed_bound", "max |θ̇₂| for (26)", "max |dtheta2| for (26)", r"\max|\dot{\theta}_2|",
                     ("", "", ""), "w1/X [rad/s]", "eq. 26", d.speed_bound))
    return out


def _canonical(x: sp.Expr, angles: tuple[sp.Symbol, ...]) -> sp.Expr:
    """The display normal form of one entry (a quotient for L(θ)). sin/cos of a constant
    angle (a URDF rpy that is not a multiple of pi/2) is shown by its 30-digit value."""
    constants = constant_angles([x])
    if constants:
        x = x.xreplace({f(c): sp.Rational(str(sp.N(f(c), 30))) for c in constants for f in (sp.sin, sp.cos)})
    try:
        return fourier_form(x, angles)
    except ValueError:
        num, den = (fourier_form(f, angles) for f in sp.fraction(sp.together(x)))
        scale = den.as_coeff_Add()[0] or 1          # the denominator's constant term becomes 1
        return sp.Mul(sp.expand(num / scale), sp.Pow(sp.expand(den / scale), -1), evaluate=False)


def tidy(value: object, exact: bool, angles: tuple[sp.Symbol, ...], formula: bool = False) -> object:
    """Entry by entry normal form (a ``formula`` stays as it is); decimals unless ``exact``.
    Display only."""
    if formula:
        return value
    if isinstance(value, sp.MatrixBase):
        value = value.applyfunc(lambda x: _canonical(x, angles))
    elif isinstance(value, sp.Expr) and value.free_symbols:
        value = _canonical(value, angles)
    return value if exact else sp.N(value, 15)


def _names(d: Derivation) -> Names:
    from derive.control.mpc import T1, T2

    return Names.of(d.dynamics.sym, extra=(T1, T2))


# -- text ---------------------------------------------------------------------------------------
def _grid(cells: list[list[str]], unicode: bool) -> list[str]:
    """A matrix of printed cells, columns aligned, with brackets."""
    cols = [max(width(row[j]) for row in cells) for j in range(len(cells[0]))]
    rows = ["  ".join(c + " " * (w - width(c)) for c, w in zip(row, cols)) for row in cells]
    if not unicode or len(rows) == 1:
        return [f"[ {r} ]" for r in rows]
    left = ["⎡"] + ["⎢"] * (len(rows) - 2) + ["⎣"]
    right = ["⎤"] + ["⎥"] * (len(rows) - 2) + ["⎦"]
    return [f"{a} {r} {b}" for a, r, b in zip(left, rows, right)]


def _text_block(e: Entry, value: object, pr: TextPrinter, unicode: bool, limit: int) -> list[str]:
    name = e.text if unicode else e.ascii
    head = f"{name}   {e.what} ({e.ref})"
    if not isinstance(value, sp.MatrixBase):
        body = wrap(name, pr.terms(sp.sympify(value)), limit, indent="")
        line = f"{body[0]}   {e.what} ({e.ref})"
        if len(body) == 1 and width(line) <= limit:
            return [line]
        return [head, *wrap(name, pr.terms(sp.sympify(value)), limit)]
    cells = [[pr.doprint(x) for x in value.row(i)] for i in range(value.rows)]
    grid = _grid(cells, unicode)
    if max(width(g) for g in grid) + 2 <= limit:
        return [head, *("  " + g for g in grid)]
    symmetric = value.is_square and value == value.T
    base = e.element[0] if unicode else e.element[1]
    notes, lines = [], []
    for i in range(value.rows):
        for j in range(value.cols):
            if symmetric and j < i:
                continue
            if value[i, j] == 0:
                notes.append("entries not listed are 0")
                continue
            index = (i + 1,) if value.cols == 1 else (i + 1, j + 1)
            lines += wrap(subscript(base, index, unicode), pr.terms(value[i, j]), limit)
    if symmetric:
        notes.insert(0, "symmetric: entries below the diagonal mirror those above")
    return [head + ("; " + "; ".join(dict.fromkeys(notes)) if notes else ""), *lines]


def render_text(d: Derivation, exact: bool = False, unicode: bool = True, limit: int = WIDTH) -> str:
    """Plain-text view of every quantity of the derivation, lines of at most ``limit`` columns."""
    arm = d.arm
    names = _names(d)
    pr = TextPrinter(names.text if unicode else names.ascii, unicode, DIGITS)
    theta, dtheta = ("θ", "θ̇") if unicode else ("theta", "dtheta")
    lines = [f"arm {arm.name}: {arm.n} joint{'s' if arm.n > 1 else ''}, {arm.description}".rstrip(", "),
             f"source: {arm.source}",
             f"notation: {theta} joint angles [rad], {dtheta} rates [rad/s], u {input_word(arm.input_units)}s "
             f"[{units_text(arm.input_units)}], e = yd - C {theta} (eq. 20)"
             + (f", wrapped to (-pi, pi] for output{'s' if len(d.wrapped) > 1 else ''} "
                f"{', '.join(str(i + 1) for i in d.wrapped)} (continuous joints)" if d.wrapped else ""),
             "numbers: exact rationals" if exact else f"numbers: {DIGITS} significant digits (--exact for rationals)",
             ""]
    for e in entries(d):
        value = tidy(e.value, exact, d.theta, e.formula)
        lines += _text_block(e, value, pr, unicode, limit)
        lines.append("")
    return "\n".join(lines)


# -- LaTeX --------------------------------------------------------------------------------------
def _tex_sum(pr: TexPrinter, expr: sp.Expr, limit: int = 140) -> list[str]:
    """A sum's terms as LaTeX, grouped into pieces of about ``limit`` characters."""
    expr = sp.sympify(expr)
    terms = TextPrinter({}, False)._as_ordered_terms(expr, order=None) if expr.is_Add else [expr]
    terms = sorted(terms, key=lambda t: not t.is_number)
    pieces, line = [], ""
    for k, t in enumerate(terms):
        text = pr.doprint(t)
        if k > 0 and not text.startswith("-"):
            text = "+ " + text
        if line and len(line) + len(text) > limit:
            pieces.append(line)
            line = text
        else:
            line = f"{line} {text}".strip()
    return [*pieces, line]


def _tex_block(d: Derivation, e: Entry, value: object, pr: TexPrinter) -> list[str]:
    label = rf"\label{{derive:{d.arm.name}:{e.key}}}"
    head = f"% {e.ascii}: {e.what} (paper {e.ref})"
    if isinstance(value, sp.MatrixBase) and max(len(pr.doprint(x)) for x in value) <= 40:
        return [head, r"\begin{equation}", f"  {e.latex} = {pr.doprint(value)}", f"  {label}", r"\end{equation}"]
    if not isinstance(value, sp.MatrixBase):
        rows = [(e.latex, sp.sympify(value))]
    else:
        symmetric = value.is_square and value == value.T
        rows = [(e.element[2] + "_{" + (f"{i + 1}" if value.cols == 1 else f"{i + 1}{j + 1}"
                                        if value.rows < 10 else f"{i + 1},{j + 1}") + "}", value[i, j])
                for i in range(value.rows) for j in range(value.cols)
                if not (symmetric and j < i) and value[i, j] != 0]
    lines = [head, r"\begin{align}"]
    for k, (lhs, x) in enumerate(rows):
        pieces = _tex_sum(pr, x)
        body = [f"  {lhs} &= {pieces[0]}"] + [rf"  &\quad {p}" for p in pieces[1:]]
        end = f" {label}" if k == len(rows) - 1 else r" \nonumber \\"
        lines += [b + r" \nonumber \\" for b in body[:-1]] + [body[-1] + end]
    return [*lines, r"\end{align}"]


def render_latex(d: Derivation, exact: bool = False) -> str:
    """LaTeX: one labelled display equation (``derive:<arm>:<key>``) per quantity."""
    pr = TexPrinter(_names(d).latex, DIGITS)
    lines = [f"% derive show --latex {d.arm.name}: {d.arm.n} joints; generated by derive",
             r"% \theta_i joint angles [rad], \dot{\theta}_i their rates [rad/s], e = y_d - C\theta (eq. 20); "
             + ("exact rationals" if exact else f"{DIGITS} significant digits")]
    for e in entries(d):
        lines += _tex_block(d, e, tidy(e.value, exact, d.theta, e.formula), pr)
    return "\n".join(lines) + "\n"


def add_arguments(parser) -> None:
    """CLI: derive show [ARM] [--latex] [--exact]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    parser.add_argument("--exact", action="store_true", help="exact rationals instead of 6 digits")
    parser.add_argument("--at", default=None, metavar="theta=...,dtheta=...[,e=...,de=...]",
                        help="print J, G, gravity, B, the free acceleration and the gains at this pose, and the "
                             "initial estimate dhat(0) for the tracking error e(0) and its rate e'(0) (default 0)")


def run(args) -> int:
    import sys

    from derive.control.pipeline import derive
    from derive.cli import load_cli_arm

    from derive.cli import report_warnings

    d = derive(load_cli_arm(args))
    report_warnings(d)
    if args.at is not None:
        from derive.cli.pose import parse_pose, pose_text

        text = pose_text(d, *parse_pose(args.at, d.n))
    elif args.latex:
        text = render_latex(d, exact=args.exact)
    else:
        encoding = (getattr(sys.stdout, "encoding", None) or "").lower()
        text = render_text(d, exact=args.exact, unicode=encoding.startswith("utf"))
    sys.stdout.write(text if text.endswith("\n") else text + "\n")
    if not args.latex:
        import textwrap

        from derive.control.sampling import summary_all

        sys.stdout.write("\n" + textwrap.fill(f"Sample time: {summary_all(d)}", 100, subsequent_indent="  ") + "\n")
    return 0
