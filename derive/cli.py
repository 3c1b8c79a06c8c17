"""Command line: ``derive show|check|generate ...``. Thin: parse, call, report.

Every DeriveError becomes one message on stderr and exit code 2.
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .errors import DeriveError
from .spec import DEFAULT_ARM, load_arm


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="derive", description=(
        "Derive and generate disturbance-observer-based and nonlinear PID controllers for "
        "robot arms (Chen's paper, eq. 11-38)."))
    sub = parser.add_subparsers(dest="command", required=True)
    show = sub.add_parser("show", help="print the derived dynamics, gains and laws")
    show.add_argument("arm", nargs="?", default=None,
                      help=f"arm file, or the name of a packaged arm (default {DEFAULT_ARM})")
    show.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    show.add_argument("--exact", action="store_true", help="exact rationals instead of 6 digits")
    return parser


def _show(args: argparse.Namespace) -> int:
    from .pipeline import derive
    from .show import render_latex, render_text

    d = derive(load_arm(args.arm))
    if args.latex:
        text = render_latex(d, exact=args.exact)
    else:
        encoding = (getattr(sys.stdout, "encoding", None) or "").lower()
        text = render_text(d, exact=args.exact, unicode=encoding.startswith("utf"))
    sys.stdout.write(text if text.endswith("\n") else text + "\n")
    return 0


COMMANDS = {"show": _show}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``derive`` console script; returns the exit code."""
    args = _parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except DeriveError as exc:
        print(f"derive: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("derive: interrupted", file=sys.stderr)
        return 130
