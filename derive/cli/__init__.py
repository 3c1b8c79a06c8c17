"""Command line: ``derive show|check|generate ...``. Thin: parse, call, report.

Each command lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int``; this module only dispatches. Every DeriveError becomes
one message on stderr and exit code 2, never a traceback.
"""
from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

from derive.errors import DeriveError, SpecError

if TYPE_CHECKING:
    from derive.model.spec import Arm

# command -> (module, help)
COMMANDS = {
    "show": ("derive.cli.show_command", "print the derived dynamics, gains and laws"),
    "check": ("derive.cli.check", "check the paper's claims as proof obligations"),
    "generate": ("derive.cli.generate", "write the C and Python controllers of an arm"),
    "embedded": ("derive.embedded.qemu", "cross-compile and run the C controller on emulated Cortex-M boards"),
    "simulate": ("derive.cli.simulate", "simulate the arm in closed loop under the generated controllers"),
    "init": ("derive.cli.init", "write a starter arm file for a URDF (then: derive generate it)"),
    "fmu": ("derive.cli.fmu", "package a controller form as a co-simulation FMU (FMI 2.0 or 3.0)"),
    "tune": ("derive.cli.tune", "choose the smallest certified observer gain W for a speed box (SDP)"),
    "sweep": ("derive.cli.sweep", "Monte-Carlo sweep of the closed loop over the arm file's [sweep] plants"),
    "excite": ("derive.cli.excite", "write an excitation trajectory for identification (Fourier series, CSV)"),
    "identify": ("derive.cli.identify", "identify the arm's parameters from a logged run; write the arm file"),
}


def version() -> str:
    """The installed distribution's version (pyproject.toml), or that of the source tree."""
    from importlib import metadata

    try:
        return metadata.version("derive")
    except metadata.PackageNotFoundError:
        return "unknown (not installed)"


class _Version(argparse.Action):
    """--version: the distribution's metadata is read only when asked (importlib.metadata costs
    about 30 ms on every command otherwise)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        print(f"derive {version()}")
        parser.exit()


def _parser(argv: Sequence[str], every: bool = False) -> argparse.ArgumentParser:
    """The command line's parser for ``argv``: every command listed with its help, and the
    arguments of the command ``argv`` names: only its module is imported (the others bring what
    it may not need: `derive show` loaded the code generator and Jinja2, 0.1 s CPU). ``every``:
    the arguments of every command (command_parsers)."""
    parser = argparse.ArgumentParser(prog="derive", description=(
        "Derive and generate disturbance-observer-based and nonlinear PID controllers for "
        "robot arms (Chen's paper, eq. 11-38)."))
    parser.add_argument("--version", action=_Version, nargs=0, help="show the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True)
    named = next((a for a in argv if not a.startswith("-")), None)   # the only top-level options are flags
    for name, (module, help_text) in COMMANDS.items():
        command = sub.add_parser(name, help=help_text)
        if every or name == named:
            importlib.import_module(module).add_arguments(command)
    return parser


def command_parsers() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The top-level parser and each command's parser (name -> parser, in COMMANDS' order) with
    every argument added, as ``derive`` builds them: what the documentation's command reference is
    generated from (docs/gen, tests/test_docs.py). Imports every command's module."""
    parser = _parser((), every=True)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, {name: sub.choices[name] for name in COMMANDS}


def add_arm_argument(parser: argparse.ArgumentParser) -> None:
    """The optional positional ARM every command takes."""
    from derive.paths import DEFAULT_ARM

    parser.add_argument("arm", nargs="?", default=None,
                        help=f"arm file, or the name of a packaged arm (default {DEFAULT_ARM})")
    parser.add_argument("--strict", action="store_true",
                        help="an implausible value (a likely unit mistake: derive.model.plausibility) is an "
                             "error (exit 2), not a warning")


def load_cli_arm(args: argparse.Namespace) -> Arm:
    """``args.arm`` loaded (derive.model.spec.load_arm), each plausibility warning and each
    element of a URDF that derive ignored although it may change the chain's dynamics
    (``<dynamics><damping>``: :attr:`Arm.warnings`) printed on stderr as
    ``derive: warning: <field>: expected ..., got ...``; with ``args.strict`` they are one
    SpecError instead (exit 2, nothing done)."""
    from derive.model.plausibility import plausibility
    from derive.model.spec import load_arm

    arm = load_arm(args.arm)
    problems = tuple(arm.warnings) + tuple(plausibility(arm))
    if problems and getattr(args, "strict", False):
        raise SpecError(arm.source, problems, title="implausible arm description (--strict)")
    for p in problems:
        print(f"derive: warning: {p}", file=sys.stderr)
    return arm


def report_warnings(derivation) -> None:
    """Print a derivation's warnings on stderr (they never change the exit code)."""
    for text in derivation.warnings:
        print(f"derive: warning: {text}", file=sys.stderr)


# The BLAS thread-pool variables a user may set; when none is, derive's commands run BLAS on one thread.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _one_blas_thread():
    """A context in which BLAS (numpy's OpenBLAS) runs on one thread, unless the user chose a number
    (one of BLAS_THREAD_VARIABLES set): derive's commands make many small LAPACK calls (batches of
    7 x 7 eigenvalue problems in the observer certificate, 21 x 21 sampled loops in the sample-time
    limits), which a thread pool only slows: `derive init` on the KUKA iiwa took 12.2 s CPU with
    OpenBLAS's two threads and 9.6 s with one. Set in the environment too, for the worker processes
    of `derive sweep` (threadpoolctl, pyproject.toml). Before NumPy is imported (``derive show``: the
    command's arguments import none) OpenBLAS is not loaded yet and reads the variables when it is:
    threadpoolctl (3 ms to import) would find no library to limit."""
    import contextlib

    if any(name in os.environ for name in BLAS_THREAD_VARIABLES):
        return contextlib.nullcontext()
    for name in BLAS_THREAD_VARIABLES:
        os.environ[name] = "1"
    if "numpy" not in sys.modules:
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, "blas")


# Commands whose own process (the console script, python -m derive) runs without the cyclic garbage
# collector: what they build (SymPy trees, arrays, CasADi graphs) holds no reference cycles to reclaim,
# and each collection of the oldest generation traverses the ~400,000 objects of SymPy's import. derive
# show my3 spent 0.1-0.2 s of its 1 s CPU in the collector (gc.callbacks: 0.06 s during the run, 0.04 s
# in the collection at exit), with the same peak memory without it (116 MB; the Panda's 219 MB / 220 MB).
# derive init on the Jaco 2: 0.13-0.14 s in 330 collections; peak 211 -> 217 MiB, Tiago torso and arm
# 234 -> 236 MiB, the 12-joint chain 452 -> 457 MiB.
NO_CYCLE_COLLECTOR = ("show", "init")


def _process_gc(command: str) -> None:
    """In the process's own run of ``command`` (one of NO_CYCLE_COLLECTOR): the cyclic collector off.
    Objects are still freed when their last reference goes (reference counting)."""
    if command in NO_CYCLE_COLLECTOR:
        gc.disable()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``derive`` console script; returns the exit code. ``argv`` None: the
    process's own command line, and then the process runs as NO_CYCLE_COLLECTOR says (never when a
    caller passes argv, as the tests do)."""
    own = argv is None
    argv = sys.argv[1:] if own else list(argv)
    args = _parser(argv).parse_args(argv)
    if own:
        _process_gc(args.command)
    try:
        with _one_blas_thread():
            return importlib.import_module(COMMANDS[args.command][0]).run(args)
    except DeriveError as exc:
        print(f"derive: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("derive: interrupted", file=sys.stderr)
        return 130
    finally:
        if own and args.command in NO_CYCLE_COLLECTOR:
            gc.freeze()   # the interpreter's collection at exit skips them (the process ends here)
