"""Rendering of ``derive check`` results: the terminal table, the Markdown report, the JSON record.

Render to strings; ``derive check`` writes them with
:func:`derive.codegen.emit.write_file` (atomic, with the umask's permissions).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import sympy as sp

from derive import jsonio
from derive.proofs.core import Counterexample, Kind, Result, Status

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation

WIDTH = 96   # detail column of the terminal table


def _one_line(text: str, width: int = WIDTH) -> str:
    """A headline cut to ``width`` characters."""
    return text if len(text) <= width else text[: width - 3] + "..."


def _summary(results: Sequence[Result]) -> str:
    """Counts by status."""
    count = {s: sum(r.outcome.status is s for r in results) for s in Status}
    errata = sum(r.erratum for r in results)
    printed = any(r.obligation.kind is Kind.PAPER for r in results)
    return (f"{len(results)} obligations: {count[Status.PROVED]} proved, {count[Status.REFUTED]} refuted"
            + (f" ({errata} errata in the paper)" if printed else "")
            + f", {count[Status.UNPROVEN]} unproven, {count[Status.NOT_APPLICABLE]} n/a")


def _verdict(code: int) -> str:
    """What the exit code means."""
    return ("exit 0: every obligation about the project's derivation is proved and every printed equation "
            "is decided" if code == 0 else
            "exit 1: an obligation about the project's derivation is not proved, or a printed equation is undecided")


def _title(d: Derivation | None) -> str:
    """What was checked: an arm, or the paper's printed equations alone."""
    return f"{d.arm.name} ({d.n} joints)" if d is not None else "--paper (the paper's printed equations)"


def render_text(d: Derivation | None, results: Sequence[Result], seconds: float, code: int,
                paper: bool = True) -> str:
    """The table (obligation, paper ref, kind, status, one-line detail), then errata, failures,
    evidence; without ``paper`` a pointer to ``derive check --paper``."""
    rows = [("obligation", "paper ref", "kind", "status", "detail")]
    rows += [(r.obligation.id, r.obligation.paper_ref, r.obligation.kind.value, r.outcome.status.value,
              _one_line(r.outcome.headline)) for r in results]
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    out = [f"derive check {_title(d)}: {_summary(results)} [{seconds:.1f} s]", ""]
    out += ["  ".join(c.ljust(w) for c, w in zip(row[:4], widths)) + "  " + row[4] for row in rows]
    errata = [r for r in results if r.erratum]
    failures = [r for r in results if r.fails_run]
    for title, group in (("Errata: printed equations refuted (they do not fail the run)", errata),
                         ("Not proved (these fail the run)", failures)):
        if group:
            out += ["", title + ":"]
            for r in group:
                out.append(f"  {r.obligation.id} ({r.obligation.paper_ref}): {r.outcome.detail.split('; at ')[0]}")
                if r.outcome.corrected:
                    out.append(f"    holds instead: {r.outcome.corrected}")
                if r.outcome.counterexample:
                    out.append(f"    counterexample: {r.outcome.counterexample.text()}")
    evidence = [r for r in results if r.outcome.evidence]
    if evidence:
        out += ["", "Numeric evidence (not part of any status):"]
        out += [f"  {r.obligation.id}: {r.outcome.evidence}" for r in evidence]
    if d is not None and d.speed_bound is not None:
        out += ["", f"Theorem 2 for {d.arm.name}: (26) holds for |theta2'| < w1/X = {float(d.speed_bound):.6g} rad/s"]
    out += [f"Observer certificate for {d.arm.name}: {r.outcome.detail.split('; W = ')[0]}"
            for r in results if r.obligation.id == "observer-certificate" and d is not None]
    if not paper:
        out += ["", "The paper's printed equations do not depend on the arm: derive check --paper "
                    "decides them (the errata)."]
    out += ["", _verdict(code)]
    return "\n".join(out) + "\n"


def _cex_json(c: Counterexample | None) -> dict | None:
    """The point (exact values as strings) and both sides, exact and as floats."""
    if c is None:
        return None
    return {"point": {str(s): str(v) for s, v in c.point}, "from_arm": [str(s) for s in c.from_arm],
            "lhs_label": c.lhs_label, "rhs_label": c.rhs_label,
            "lhs": [str(x) for x in c.lhs], "rhs": [str(x) for x in c.rhs],
            "lhs_float": _floats(c.lhs), "rhs_float": _floats(c.rhs)}


def _floats(values) -> list[float] | jsonio.Undefined:
    """The exact values as doubles, or undefined (with why) when one is not a finite double."""
    try:
        out = [float(x) for x in values]
    except (OverflowError, TypeError, ValueError):
        out = [float("nan")]
    if all(math.isfinite(x) for x in out):
        return out
    return jsonio.Undefined("a value is not a finite double; the exact values are in lhs and rhs")


def render_json(d: Derivation | None, results: Sequence[Result], seconds: float, code: int) -> str:
    """{"arm", "exit_code", "seconds", "obligations": [{"id", "paper_ref", "kind", "status", "detail",
    "corrected", "counterexample", "evidence"}], "payload" (with a [payload] range: derive.control.payload.text.record)}."""
    doc = {"arm": d.arm.name if d else None, "n": d.n if d else None, "exit_code": code, "seconds": round(seconds, 3),
           "obligations": [{"id": r.obligation.id, "paper_ref": r.obligation.paper_ref,
                            "kind": r.obligation.kind.value, "status": r.outcome.status.value,
                            "statement": r.obligation.statement, "detail": r.outcome.detail,
                            "corrected": r.outcome.corrected, "counterexample": _cex_json(r.outcome.counterexample),
                            "evidence": r.outcome.evidence} for r in results]}
    if d is not None and d.arm.payload is not None:
        from derive.control.payload.text import record

        doc["payload"] = record(d)   # the payload-range obligation's numbers (derive.control.payload)
    return jsonio.dumps(doc, sort_keys=False)


def _md_cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


def _latex_point(c: Counterexample) -> str:
    """The counterexample's point in LaTeX."""
    return ",\\ ".join(f"{sp.latex(s)} = {sp.latex(v)}" for s, v in c.point)


def render_markdown(d: Derivation | None, results: Sequence[Result], seconds: float, code: int) -> str:
    """The table and, per obligation, statement, derivation (LaTeX), correction and counterexample."""
    what = (f"Arm `{d.arm.name}` ({d.n} joints), source `{Path(d.arm.source).name}`." if d is not None else
            "The paper's printed equations, in generic symbols (arm-independent).")
    out = [f"# derive check: {d.arm.name if d is not None else 'the paper'}", "",
           f"{what} {_summary(results)}; {seconds:.1f} s.", "", f"**{_verdict(code)}**", "",
           "Kinds: *project* obligations are about the project's own derivation and must be proved; "
           "*paper* obligations encode an equation as printed: refuted means an erratum.", "",
           "| obligation | paper ref | kind | status | detail |", "|---|---|---|---|---|"]
    out += [f"| `{r.obligation.id}` | {r.obligation.paper_ref} | {r.obligation.kind.value} | "
            f"**{r.outcome.status.value}** | {_md_cell(_one_line(r.outcome.headline, 140))} |" for r in results]
    if d is not None and d.speed_bound is not None:
        out += ["", f"Theorem 2 for this arm: condition (26) holds for "
                    f"$|\\dot\\theta_2| < w_1/X = {sp.latex(d.speed_bound)} \\approx {float(d.speed_bound):.6g}$ rad/s."]
    out += ["", "## Derivations", ""]
    for r in results:
        o, ob = r.outcome, r.obligation
        out += [f"### `{ob.id}` ({ob.paper_ref}, {ob.kind.value}): {o.status.value}", "",
                f"*Statement.* {ob.statement}.", ""]
        if ob.latex:
            out += ["*As printed.*", "", f"$$ {ob.latex} $$", ""]
        out += [f"*Finding.* {o.detail}.", ""]
        for line in o.latex:
            out += [f"$$ {line} $$", ""]
        if o.corrected:
            out += [f"*Holds instead.* {o.corrected}.", ""]
        c = o.counterexample
        if c is not None:
            out += ["*Counterexample.*", "", f"$$ {_latex_point(c)} $$", "",
                    f"$$ \\text{{{c.lhs_label}}} = {sp.latex(c.lhs)} \\neq {sp.latex(c.rhs)} = \\text{{{c.rhs_label}}} $$", ""]
        if o.evidence:
            out += [f"*Numeric evidence (not part of the status).* {o.evidence}.", ""]
    return "\n".join(out)
