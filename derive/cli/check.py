"""``derive check [ARM] [--paper] [--report FILE.md] [--json FILE]``: the paper's claims as proof obligations.

``derive check ARM`` runs the obligations about the arm's own derivation
(:mod:`derive.proofs.project`, :mod:`derive.proofs.arm`, kind ``project``);
``derive check --paper`` decides the paper's printed equations
(:mod:`derive.proofs.paper_claims`, :mod:`derive.proofs.observer`, kind
``paper``) once, in generic symbols: they do not depend on the arm, so they
are not re-checked for every arm. Both together: ``derive check ARM --paper``.
Prints the table, and writes the Markdown report and the JSON record on request.

Exit code: 0 when every project obligation is proved (or does not apply to
the arm) and no printed equation is left undecided; a refuted printed equation
is an erratum, reported, and does not fail the run; anything else is exit 1.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from derive.proofs.core import Obligation, Result, exit_code

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation


def project_obligations() -> tuple[Obligation, ...]:
    """The obligations about an arm's derivation (kind ``project``), in reading order."""
    from derive.proofs import arm as proofs_arm
    from derive.proofs import certificate as proofs_certificate
    from derive.proofs import dynamics as proofs_dynamics
    from derive.proofs import payload as proofs_payload
    from derive.proofs import project as proofs_project

    return (*proofs_project.OBLIGATIONS, *proofs_arm.OBLIGATIONS, *proofs_dynamics.OBLIGATIONS,
            *proofs_certificate.OBLIGATIONS, *proofs_payload.OBLIGATIONS)


def paper_obligations() -> tuple[Obligation, ...]:
    """The paper's printed equations (kind ``paper``, arm-independent), in reading order."""
    from derive.proofs import observer as proofs_observer
    from derive.proofs import paper_claims as proofs_paper

    return (*proofs_paper.OBLIGATIONS, *proofs_observer.OBLIGATIONS)


def obligations() -> tuple[Obligation, ...]:
    """Every obligation, in reading order: the project's derivation first, then the paper."""
    return (*project_obligations(), *paper_obligations())


def check(d: Derivation | None, selected: tuple[Obligation, ...] | None = None,
          show: bool = False) -> tuple[Result, ...]:
    """Run the obligations (default: all) on a Derivation; ``None`` runs the paper's
    obligations in generic symbols (an arm only seeds their counterexample search).
    ``show``: a progress bar on a terminal (derive.progress)."""
    from derive.progress import progress
    from derive.proofs.core import run as run_all

    if selected is None:
        selected = obligations() if d is not None else paper_obligations()
    results: list[Result] = []
    with progress(total=len(selected), desc="check", unit="obligation", disable_bar=not show) as bar:
        for ob in selected:
            results += run_all((ob,), d)
            bar.update()
    return tuple(results)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI: derive check [ARM] [--paper] [--report FILE.md] [--json FILE]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--paper", action="store_true",
                        help="check the paper's printed equations (arm-independent, about 15 s of CPU); "
                             "alone, or with ARM as well as the arm's obligations")
    parser.add_argument("--report", metavar="FILE.md", type=Path,
                        help="write the table and the derivations as Markdown with LaTeX")
    parser.add_argument("--json", metavar="FILE", type=Path,
                        help='write {"obligations": [{"id", "paper_ref", "status", "detail", "corrected", ...}]}')


def run(args: argparse.Namespace) -> int:
    """Derive the arm, check its obligations (and the paper's with --paper), report;
    the exit code of the module docstring."""
    from derive.codegen.emit import write_file
    from derive.proofs.report import render_json, render_markdown, render_text
    from derive.cli import report_warnings
    from derive.control.pipeline import derive
    from derive.cli import load_cli_arm

    start = time.perf_counter()
    d = None
    results: tuple[Result, ...] = ()
    if args.arm is not None or not args.paper:
        d = derive(load_cli_arm(args))
        report_warnings(d)
        results = check(d, project_obligations(), show=True)
    if args.paper:
        results += check(None, paper_obligations(), show=True)
    seconds = time.perf_counter() - start
    code = exit_code(results)
    sys.stdout.write(render_text(d, results, seconds, code, paper=args.paper))
    if d is not None:
        from derive.control.limit_text import summary_all

        sys.stdout.write(f"Sample time of {d.arm.name}: {summary_all(d)}\n")
        from derive.control.payload.text import summary as payload_summary

        if (line := payload_summary(d)) is not None:
            sys.stdout.write(f"Payload of {d.arm.name}: {line}\n")
    if args.report is not None:
        write_file(args.report, render_markdown(d, results, seconds, code))
    if args.json is not None:
        write_file(args.json, render_json(d, results, seconds, code))
    return code
