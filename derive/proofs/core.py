"""Proof obligations: the type, the deciders and the runner of ``derive check``.

An :class:`Obligation` encodes one claim of the paper (an equation as printed,
a line of a printed derivation, a theorem) or one property of the project's own
derivation. Its check returns an :class:`Outcome`:

* ``proved``: SymPy settled the claim exactly (a zero canonical form, a sign
  fact from SymPy's assumptions on an explicit parametrisation);
* ``refuted``: the canonical form of lhs - rhs is not zero; the outcome carries
  a concrete :class:`Counterexample` (exact numbers, both sides) and, for a
  printed equation, the statement that does hold;
* ``unproven``: SymPy cannot decide it (numeric samples may be given as
  evidence, never as the status);
* ``n/a``: the claim does not apply to this arm (theorem 2 for n != 2).

Kinds: ``project`` obligations are about the project's derivation and must be
proved; ``paper`` obligations are printed equations: refuted means an erratum,
reported without failing the run (:func:`exit_code`).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING

import sympy as sp
from sympy.polys.matrices import DomainMatrix

from derive.proofs.exact import Field, Undecidable, evaluate, sample_angle, sample_value

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation


class Status(str, Enum):
    """The verdict of one obligation (``n/a``: does not apply to this arm)."""

    PROVED = "proved"
    REFUTED = "refuted"
    UNPROVEN = "unproven"
    NOT_APPLICABLE = "n/a"


class Kind(str, Enum):
    """Whose claim: the project's derivation, or the paper as printed."""

    PROJECT = "project"   # the project's own derivation: anything but proved fails the run
    PAPER = "paper"       # an equation as printed: refuted is an erratum, reported


@dataclass(frozen=True)
class Counterexample:
    """A point (exact values) where the two sides of a refuted statement differ."""

    point: tuple[tuple[sp.Symbol, sp.Expr], ...]
    lhs: sp.Matrix
    rhs: sp.Matrix
    lhs_label: str = "printed"
    rhs_label: str = "derived"
    from_arm: tuple[sp.Symbol, ...] = ()

    def text(self) -> str:
        """One line: the point (the arm's parameter values named only), then both sides as numbers."""
        at = ", ".join(f"{s} = {_num(v)}" for s, v in self.point if s not in self.from_arm)
        if self.from_arm:
            at += f" and the arm's {', '.join(map(str, self.from_arm))}"
        return f"at {at}: {self.lhs_label} {_vec(self.lhs)} != {self.rhs_label} {_vec(self.rhs)}"


@dataclass(frozen=True)
class Outcome:
    """What a check found. ``summary``: the one-line detail of the table (default: the
    first clause of ``detail``); ``latex``: display lines of the derivation for the report."""

    status: Status
    detail: str
    corrected: str | None = None
    counterexample: Counterexample | None = None
    evidence: str | None = None
    latex: tuple[str, ...] = ()
    summary: str = ""

    @property
    def headline(self) -> str:
        """The table's one-line detail."""
        return self.summary or self.detail.split("; ")[0]


@dataclass(frozen=True)
class Obligation:
    """One claim: id, the paper's reference (equation or theorem), kind, the
    statement in words, the check run on a Derivation, and (paper kind) the
    equation as printed in LaTeX, for the report."""

    id: str
    paper_ref: str
    kind: Kind
    statement: str
    check: Callable[["Derivation"], Outcome] = field(repr=False, compare=False)
    latex: str = ""


@dataclass(frozen=True)
class Result:
    """An obligation, its outcome on one arm and the seconds its check took."""

    obligation: Obligation
    outcome: Outcome
    seconds: float

    @property
    def fails_run(self) -> bool:
        """Project: anything but proved / n/a fails; paper: unproven fails, refuted is an erratum."""
        status = self.outcome.status
        if status in (Status.PROVED, Status.NOT_APPLICABLE):
            return False
        return self.obligation.kind is Kind.PROJECT or status is Status.UNPROVEN

    @property
    def erratum(self) -> bool:
        """A printed equation of the paper that is refuted."""
        return self.obligation.kind is Kind.PAPER and self.outcome.status is Status.REFUTED


def run(obligations: Sequence[Obligation], d: "Derivation") -> tuple[Result, ...]:
    """Check every obligation on ``d``; an undecidable expression becomes ``unproven``."""
    results = []
    for ob in obligations:
        start = time.perf_counter()
        try:
            outcome = ob.check(d)
        except Undecidable as exc:
            outcome = Outcome(Status.UNPROVEN, f"SymPy cannot decide: {exc}")
        results.append(Result(ob, outcome, time.perf_counter() - start))
    return tuple(results)


def exit_code(results: Sequence[Result]) -> int:
    """0 when every project obligation is proved (or n/a) and no paper one is unproven."""
    return 1 if any(r.fails_run for r in results) else 0


def not_applicable(reason: str) -> Outcome:
    """The claim does not apply to this arm (e.g. theorem 2 for n != 2)."""
    return Outcome(Status.NOT_APPLICABLE, reason)


# -- identities ---------------------------------------------------------------------------
Sides = Callable[[Mapping[sp.Symbol, sp.Expr]], tuple[sp.Matrix, sp.Matrix]]


def find_point(F: Field, residual: DomainMatrix, need: Sequence[DomainMatrix] = (),
               base: Mapping[sp.Symbol, sp.Expr] | None = None, tries: int = 24,
               also: Sequence[sp.Symbol] = ()) -> dict | None:
    """Exact point where some entry of ``residual`` is non-zero (and ``need`` is finite).

    The point gives a value to every symbol of ``residual``, ``need`` and
    ``also``. Symbols in ``base`` keep those values (the arm's parameters);
    others take deterministic samples respecting sign assumptions; angles take
    values with rational sine and cosine.
    """
    base = dict(base or {})
    exprs = [F.to_sympy(m) for m in (residual, *need)]
    syms = sorted(set().union(*(e.free_symbols for e in exprs), also), key=sp.default_sort_key)
    for k in range(tries):
        point = {}
        for i, s in enumerate(syms):
            if s in F.angles:
                point[s] = sample_angle(k + i)
            elif s in base and k < tries // 2:
                point[s] = base[s]
            else:
                point[s] = sample_value(s, 3 * k + i)
        values = [evaluate(e, point) for e in exprs]
        if any(v.has(sp.zoo, sp.nan, sp.oo) for v in values):
            continue
        if any(x != 0 for x in values[0]):
            return point
    return None


def equal(F: Field, lhs: DomainMatrix, rhs: DomainMatrix, *, proved: str, refuted: str,
          base: Mapping[sp.Symbol, sp.Expr] | None = None, corrected: str | None = None,
          labels: tuple[str, str] = ("printed", "derived"), sides: Sides | None = None,
          residual: DomainMatrix | None = None, latex: tuple[str, ...] = ()) -> Outcome:
    """Decide lhs = rhs exactly; refuted with a counterexample that shows both sides.

    ``residual`` (default lhs - rhs) is what is decided: a form that is zero iff
    the statement holds (e.g. the statement premultiplied by an invertible
    matrix); ``sides`` then evaluates the statement itself at a point.
    """
    res = lhs - rhs if residual is None else residual
    if F.is_zero(res):
        return Outcome(Status.PROVED, proved, latex=latex)
    point = find_point(F, res, (lhs, rhs), base, also=F.symbols if sides else ())
    cex = None
    if point is not None:
        left, right = sides(point) if sides else (F.at(lhs, point), F.at(rhs, point))
        arm = tuple(s for s, v in point.items() if base and s in base and base[s] == v)
        cex = Counterexample(tuple(point.items()), left, right, *labels, from_arm=arm)
    detail = refuted + (f"; {cex.text()}" if cex else "; no exact counterexample found in 24 samples")
    return Outcome(Status.REFUTED, detail, corrected, cex, latex=latex)


@dataclass(frozen=True)
class Line:
    """One printed line of a derivation and, when it is wrong, what should stand there."""

    label: str
    printed: DomainMatrix
    corrected_text: str | None = None
    corrected: DomainMatrix | None = None


def lines(F: Field, truth: DomainMatrix, printed: Sequence[Line], *, what: str,
          base: Mapping[sp.Symbol, sp.Expr] | None = None, latex: tuple[str, ...] = ()) -> Outcome:
    """Check each printed line against the derived ``truth``, line by line, as printed."""
    good, bad, first = [], [], None
    for ln in printed:
        out = equal(F, ln.printed, truth, proved="", refuted=f"{ln.label} differs from {what}", base=base)
        if out.status is Status.PROVED:
            good.append(ln.label)
            continue
        fix = ""
        if ln.corrected is not None:
            ok = F.is_zero(ln.corrected - truth)
            fix = f" (corrected: {ln.corrected_text}: {'proved' if ok else 'NOT proved'})"
        bad.append(f"{ln.label} refuted{fix}")
        first = first or (ln, out)
    total = len(printed)
    if first is None:
        return Outcome(Status.PROVED, f"{', '.join(good)} equal {what}", latex=latex,
                       summary=f"all {total} printed lines equal {what}")
    ln, out = first
    detail = "; ".join(bad) + (f"; {', '.join(good)} proved" if good else "")
    cex = out.counterexample
    summary = f"{len(bad)} of {total} lines refuted ({ln.label}: {ln.corrected_text or 'wrong'})"
    return Outcome(Status.REFUTED, detail + (f"; {cex.text()}" if cex else ""), ln.corrected_text, cex, latex=latex,
                   summary=summary)


def combine(parts: Sequence[Outcome], prefix: str = "", summary: str = "") -> Outcome:
    """All parts of one obligation: the worst status, the details joined; ``summary``
    is the headline when every part is proved, else the first failing part's headline."""
    order = (Status.REFUTED, Status.UNPROVEN, Status.NOT_APPLICABLE, Status.PROVED)
    status = min((p.status for p in parts), key=order.index)
    if status is not Status.PROVED:
        summary = next(p.headline for p in parts if p.status is status)
    detail = prefix + "; ".join(p.detail for p in parts if p.detail)
    cex = next((p.counterexample for p in parts if p.counterexample), None)
    corrected = next((p.corrected for p in parts if p.corrected), None)
    evidence = "; ".join(p.evidence for p in parts if p.evidence) or None
    latex = tuple(x for p in parts for x in p.latex)
    return Outcome(status, detail, corrected, cex, evidence, latex, summary)


# -- signs ---------------------------------------------------------------------------------
def positive(expr: sp.Expr, *, proved: str, what: str, strict: bool = True,
             sampler: Callable[[int], Mapping[sp.Symbol, sp.Expr]] | None = None) -> Outcome:
    """Decide expr > 0 (or >= 0) from SymPy's assumptions on its symbols.

    True is a proof; False a refutation (a sampled point shows the sign);
    None is ``unproven`` (``sampler`` may add numeric evidence).
    """
    fact = expr.is_positive if strict else expr.is_nonnegative
    rel = ">" if strict else ">="
    if fact is True:
        return Outcome(Status.PROVED, proved)
    evidence = None
    if sampler is not None:
        values = [float(expr.xreplace(dict(sampler(k)))) for k in range(200)]
        evidence = f"{len(values)} samples: min {min(values):.6g}"
    if fact is False:
        cex = None
        for k in range(200 if sampler else 0):
            pt = dict(sampler(k))
            v = expr.xreplace(pt)
            if (v <= 0) if strict else (v < 0):
                cex = Counterexample(tuple(pt.items()), sp.Matrix([v]), sp.Matrix([0]), what, "0")
                break
        return Outcome(Status.REFUTED, f"{what} {rel} 0 is false" + (f"; {cex.text()}" if cex else ""),
                       counterexample=cex, evidence=evidence)
    return Outcome(Status.UNPROVEN, f"SymPy cannot settle {what} {rel} 0 from its assumptions", evidence=evidence)


def _num(v: sp.Expr) -> str:
    """Exact value, with a decimal when it is not a small integer or fraction."""
    v = sp.sympify(v)
    text = str(v)
    if v.is_Integer or (v.is_Rational and len(text) <= 7):
        return text
    if v.is_number:
        return f"{text} (~{float(v):.6g})" if len(text) <= 12 else f"~{float(v):.9g}"
    return text


def _vec(m: sp.MatrixBase) -> str:
    """Compact numbers of a matrix: [a, b] or [[a, b], [c, d]]."""
    def f(v: sp.Expr) -> str:
        v = sp.sympify(v)
        return f"{float(v):.6g}" if v.is_number else str(v)
    if m.cols == 1:
        return "[" + ", ".join(f(x) for x in m) + "]"
    return "[" + ", ".join("[" + ", ".join(f(x) for x in m.row(i)) + "]" for i in range(m.rows)) + "]"
