"""``derive check [ARM] [--report FILE.md] [--json FILE]``: the paper's claims as proof obligations.

Runs every obligation (:mod:`derive.proofs.project`, :mod:`derive.proofs.arm`:
the project's own derivation; :mod:`derive.proofs.paper_claims`,
:mod:`derive.proofs.observer`: the paper's equations as printed), prints the
table, and writes the Markdown report and the JSON record on request.

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


def obligations() -> tuple[Obligation, ...]:
    """Every obligation, in reading order: the project's derivation first, then the paper."""
    from derive.proofs import arm as proofs_arm
    from derive.proofs import observer as proofs_observer
    from derive.proofs import paper_claims as proofs_paper
    from derive.proofs import project as proofs_project

    return (*proofs_project.OBLIGATIONS, *proofs_arm.OBLIGATIONS, *proofs_paper.OBLIGATIONS,
            *proofs_observer.OBLIGATIONS)


def check(d: Derivation, selected: tuple[Obligation, ...] | None = None) -> tuple[Result, ...]:
    """Run the obligations on a Derivation."""
    from derive.proofs.core import run as run_all

    return run_all(obligations() if selected is None else selected, d)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI: derive check [ARM] [--report FILE.md] [--json FILE]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--report", metavar="FILE.md", type=Path,
                        help="write the table and the derivations as Markdown with LaTeX")
    parser.add_argument("--json", metavar="FILE", type=Path,
                        help='write {"obligations": [{"id", "paper_ref", "status", "detail", "corrected", ...}]}')


def run(args: argparse.Namespace) -> int:
    """Derive the arm, check every obligation, report; the exit code of the module docstring."""
    from derive.proofs.report import render_json, render_markdown, render_text, write_text
    from derive.cli import report_warnings
    from derive.control.pipeline import derive
    from derive.model.spec import load_arm

    start = time.perf_counter()
    d = derive(load_arm(args.arm))
    report_warnings(d)
    results = check(d)
    seconds = time.perf_counter() - start
    code = exit_code(results)
    sys.stdout.write(render_text(d, results, seconds, code))
    if args.report is not None:
        write_text(args.report, render_markdown(d, results, seconds, code))
    if args.json is not None:
        write_text(args.json, render_json(d, results, seconds, code))
    return code
