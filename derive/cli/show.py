"""``derive show``: the Derivation as readable text or LaTeX.

Text fits ``WIDTH`` (100) columns: a matrix whose grid fits is printed as a grid,
any other is listed entry by entry (J₁₂ = ...), sums wrapped between terms. The
entries are shown in their Fourier form (:mod:`derive.cli.display`: products of
sines and cosines as sines and cosines of sums; prismatic coordinates as
polynomial factors), never simplified as whole matrices; 6 significant digits
unless ``--exact``. A matrix of more than 200 terms is shown at a stated
precision: the terms below a tolerance (1, 2, 5 x 10^k from 1e-6 up, relative to
the matrix's largest) are left out and each entry says how many and the bound of
their sum. Beyond ``FULL_JOINTS`` joints (unless ``--full``), G is shown as
C(θ, θ̇)θ̇ + g(θ) + F θ̇ with g and F listed, and P, D, N in terms of the entries
of J and G (eq. 35-38 as the code computes them): a 7-joint arm fits a few
screens. Names are the paper's (θ̇, ÿd, ė(0), :mod:`derive.cli.notation`); LaTeX
gives each quantity one labelled display equation.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.cli.display import BUDGET, Shown, shown
from derive.cli.notation import SUB, Names, TexPrinter, TextPrinter, subscript, width, wrap
from derive.control.pipeline import Derivation
from derive.model.actuators import input_word, units_text
from derive.model.spec import gain_units_text

WIDTH = 100
DIGITS = 6
FULL_JOINTS = 4   # beyond: G as C q' + g + F q', P, D, N over the entries of J and G (unless --full)


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
    plain: bool = False        # shown as it is, numbers to 6 digits (laws over the entries of J and G)


def _b_what(d: Derivation) -> str:
    """What B maps: joint torque per volt (DC motors), per motor torque (torque actuation: the gear ratio)."""
    per = {"V": "volt", "N m": "N m of motor torque (the gear ratio)", "N": "N of motor force (the gear ratio)"}
    units = list(dict.fromkeys(d.arm.input_units))
    return "input matrix, joint torque per " + (per[units[0]] if len(units) == 1 else "unit of u (V or N m per motor)")


def entries(d: Derivation, full: bool = False) -> list[Entry]:
    """Every quantity shown, in reading order (``full``: as for a small arm, whatever n)."""
    k1, k2 = d.k_formulas   # factored already (derive.control.mpc.gains)
    E = Entry
    brief = not full and d.n > FULL_JOINTS and d.formal is not None
    out = [E("J", "J(θ)", "J(theta)", r"J(\theta)", ("J", "J", "J"), "inertia matrix", "eq. 12, a6", d.J)]
    if brief:
        out += [
            E("G", "G(θ, θ̇)", "G(theta, dtheta)", r"G(\theta, \dot{\theta})", ("G", "G", "G"),
              "Coriolis, centrifugal, gravity and damping torques: C(θ, θ̇) θ̇ + g(θ) + F θ̇, the Coriolis part "
              f"quadratic in θ̇ (derive show --full lists it, derive show --at evaluates it)", "eq. 12", None),
            E("g", "g(θ)", "g(theta)", r"g(\theta)", ("g", "g", "g"), "gravity torques", "eq. 12",
              d.numeric(d.dynamics.gravity)),
            E("F", "F", "F", "F", ("F", "F", "F"), "motor and viscous damping, F θ̇ in G", "eq. 12",
              d.numeric(d.dynamics.damping)),
        ]
    else:
        out.append(E("G", "G(θ, θ̇)", "G(theta, dtheta)", r"G(\theta, \dot{\theta})", ("G", "G", "G"),
                     "Coriolis, centrifugal, gravity and damping torques", "eq. 12", d.G))
    out += [
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
    src = d.formal if brief else d
    over = " over the entries of J" if brief else ""
    out += [
        E("P", "P(θ)", "P(theta)", r"P(\theta)", ("P", "P", "P"), "proportional gain" + over, "eq. 35", src.P,
          plain=brief),
        E("D", "D(θ)", "D(theta)", r"D(\theta)", ("D", "D", "D"), "derivative gain" + over, "eq. 36", src.D,
          plain=brief),
        E("I", "I", "I", "I", ("I", "I", "I"), "integral gain", "eq. 37", d.I),
        E("N", "N(θ, θ̇)", "N(theta, dtheta)", r"N(\theta, \dot{\theta})", ("N", "N", "N"),
          "nonlinear term" + (" over the entries of J and G" if brief else ""), "eq. 38", src.N, plain=brief),
        E("dhat0", "d̂(0)", "dhat(0)", r"\hat{d}(0)", ("d̂", "dhat", r"\hat{d}"),
          "initial disturbance estimate", "eq. 30; derived, not the printed eq. 31", d.dhat0),
    ]
    if d.lumped is not None:
        out += [E(k, k, k, k if k == "X" else f"{k[0]}_{k[1]}", (k, k, k), "lumped inertia parameter", "eq. a6", v)
                for k, v in d.lumped.items()]
        out.append(E("speed_bound", "max |θ̇₂| for (26)", "max |dtheta2| for (26)", r"\max|\dot{\theta}_2|",
                     ("", "", ""), "w1/X [rad/s]", "eq. 26", d.speed_bound))
    return out


def tidy(e: Entry, exact: bool, angles: tuple[sp.Symbol, ...], full: bool = False) -> Shown:
    """An entry's display form (derive.cli.display); a ``formula`` stays as it is, a ``plain``
    one is printed as it is with its numbers to 6 digits. Display only."""
    if e.formula or e.value is None:
        return Shown(e.value, {})
    if e.plain:
        return Shown(e.value if exact else e.value.applyfunc(lambda x: sp.N(x, 15)), {})
    return shown(e.value, angles, exact, budget=None if full else BUDGET)


def _names(d: Derivation) -> Names:
    from derive.control.mpc import T1, T2

    names = Names.of(d.dynamics.sym, extra=(T1, T2))
    if d.formal is None:
        return names
    text, ascii_, latex = dict(names.text), dict(names.ascii), dict(names.latex)
    ph = d.formal.dynamics.ph
    for m, base in ((ph.J, "J"), (ph.G, "G")):
        for i in range(m.rows):
            for j in range(m.cols):
                idx = (i + 1,) if m.cols == 1 else (i + 1, j + 1)
                text[m[i, j]] = base + "".join(str(k) for k in idx).translate(SUB) if d.n < 10 else \
                    base + ",".join(str(k) for k in idx).translate(SUB)
                ascii_[m[i, j]] = base + "_".join(str(k) for k in idx) if d.n >= 10 else base + "".join(map(str, idx))
                latex[m[i, j]] = f"{base}_{{{','.join(map(str, idx)) if d.n >= 10 else ''.join(map(str, idx))}}}"
    return Names(text, ascii_, latex)


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


def _precision(sh: Shown) -> str:
    return (f"terms below {sh.tol:.0e} of its largest left out (over {BUDGET} terms; derive show --full "
            "lists every one)"
            if sh.tol else "")


def _text_block(e: Entry, sh: Shown, pr: TextPrinter, unicode: bool, limit: int) -> list[str]:
    name = e.text if unicode else e.ascii
    value = sh.value
    head = f"{name}   {e.what} ({e.ref})"
    if value is None:
        return _fill(head, limit)
    if not isinstance(value, sp.MatrixBase):
        body = wrap(name, pr.terms(sp.sympify(value)), limit, indent="")
        line = f"{body[0]}   {e.what} ({e.ref})"
        if len(body) == 1 and width(line) <= limit:
            return [line]
        return [*_fill(head, limit), *wrap(name, pr.terms(sp.sympify(value)), limit)]
    # each entry printed once: its terms (TextPrinter.terms) make both its grid cell (doprint joins
    # them with spaces) and its lines when the grid does not fit
    printed = [[pr.terms(x) for x in value.row(i)] for i in range(value.rows)]
    grid = _grid([[" ".join(t) for t in row] for row in printed], unicode)
    if not sh.notes and max(width(g) for g in grid) + 2 <= limit:
        return [*_fill(head + (f"; {sh.note}" if sh.note else ""), limit), *("  " + g for g in grid)]
    symmetric = value.is_square and value == value.T
    base = e.element[0] if unicode else e.element[1]
    notes, lines = [], []
    if sh.tol:
        notes.append(_precision(sh))
    if sh.note:
        notes.append(sh.note)
    for i in range(value.rows):
        for j in range(value.cols):
            if symmetric and j < i:
                continue
            k = i * value.cols + j
            if value[i, j] == 0 and k not in sh.notes:
                notes.append("entries not listed are 0")
                continue
            index = (i + 1,) if value.cols == 1 else (i + 1, j + 1)
            terms = printed[i][j] if value[i, j] != 0 else ["0"]
            if k in sh.notes:
                terms = terms + [f"({sh.notes[k]})"]
            lines += wrap(subscript(base, index, unicode), terms, limit)
    if symmetric:
        notes.insert(0, "symmetric: entries below the diagonal mirror those above")
    return [*_fill(head + ("; " + "; ".join(dict.fromkeys(notes)) if notes else ""), limit), *lines]


def _fill(text: str, limit: int, indent: str = "    ") -> list[str]:
    """``text`` broken between words into lines of at most ``limit`` columns (display width)."""
    lines, line = [], ""
    for word in text.split(" "):
        candidate = f"{line} {word}" if line else word
        if line and width(candidate) > limit:
            lines.append(line)
            line = indent + word
        else:
            line = candidate
    return [*lines, line]


def render_text(d: Derivation, exact: bool = False, unicode: bool = True, limit: int = WIDTH,
                full: bool = False) -> str:
    """Plain-text view of every quantity of the derivation, lines of at most ``limit`` columns
    (``full``: every term of every quantity, whatever the arm's size)."""
    arm = d.arm
    names = _names(d)
    pr = TextPrinter(names.text if unicode else names.ascii, unicode, DIGITS)
    theta, dtheta = ("θ", "θ̇") if unicode else ("theta", "dtheta")
    head = [f"arm {arm.name}: {arm.n} joint{'s' if arm.n > 1 else ''}, {arm.description}".rstrip(", "),
            f"source: {arm.source}",
             f"notation: {theta} joint coordinates [rad or m], {dtheta} rates, u {input_word(arm.input_units)}s "
             f"[{units_text(arm.input_units)}], e = yd - C {theta} (eq. 20)"
             + (f", wrapped to (-pi, pi] for output{'s' if len(d.wrapped) > 1 else ''} "
                f"{', '.join(str(i + 1) for i in d.wrapped)} (continuous joints)" if d.wrapped else ""),
             "numbers: exact rationals" if exact else f"numbers: {DIGITS} significant digits (--exact for rationals)"]
    lines = [x for h in head for x in _fill(h, limit)] + [""]
    for e in entries(d, full):
        lines += _text_block(e, tidy(e, exact, d.dynamics.angles, full), pr, unicode, limit)
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


def _tex_block(d: Derivation, e: Entry, sh: Shown, pr: TexPrinter) -> list[str]:
    label = rf"\label{{derive:{d.arm.name}:{e.key}}}"
    head = f"% {e.ascii}: {e.what} (paper {e.ref})" + (f"; {_precision(sh)}" if sh.tol else "") \
        + (f"; {sh.note}" if sh.note else "")
    value = sh.value
    if value is None:
        return [head]
    if isinstance(value, sp.MatrixBase) and not sh.notes and max(len(pr.doprint(x)) for x in value) <= 40:
        return [head, r"\begin{equation}", f"  {e.latex} = {pr.doprint(value)}", f"  {label}", r"\end{equation}"]
    if not isinstance(value, sp.MatrixBase):
        rows = [(e.latex, sp.sympify(value), None)]
    else:
        symmetric = value.is_square and value == value.T
        rows = [(e.element[2] + "_{" + (f"{i + 1}" if value.cols == 1 else f"{i + 1}{j + 1}"
                                        if value.rows < 10 else f"{i + 1},{j + 1}") + "}", value[i, j],
                 sh.notes.get(i * value.cols + j))
                for i in range(value.rows) for j in range(value.cols)
                if not (symmetric and j < i) and (value[i, j] != 0 or i * value.cols + j in sh.notes)]
    lines = [head, r"\begin{align}"]
    for k, (lhs, x, note) in enumerate(rows):
        pieces = _tex_sum(pr, x)
        if note:
            pieces.append(rf"\text{{({note})}}")
        body = [f"  {lhs} &= {pieces[0]}"] + [rf"  &\quad {p}" for p in pieces[1:]]
        end = f" {label}" if k == len(rows) - 1 else r" \nonumber \\"
        lines += [b + r" \nonumber \\" for b in body[:-1]] + [body[-1] + end]
    return [*lines, r"\end{align}"]


def render_latex(d: Derivation, exact: bool = False, full: bool = False) -> str:
    """LaTeX: one labelled display equation (``derive:<arm>:<key>``) per quantity."""
    pr = TexPrinter(_names(d).latex, DIGITS)
    lines = [f"% derive show --latex {d.arm.name}: {d.arm.n} joints; generated by derive",
             r"% \theta_i joint coordinates [rad, or m], \dot{\theta}_i their rates, e = y_d - C\theta (eq. 20); "
             + ("exact rationals" if exact else f"{DIGITS} significant digits")]
    for e in entries(d, full):
        lines += _tex_block(d, e, tidy(e, exact, d.dynamics.angles, full), pr)
    return "\n".join(lines) + "\n"
