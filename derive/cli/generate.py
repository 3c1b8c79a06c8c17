"""``derive generate``: derive an arm and write generated/<arm>/ (derive's files as one set; others kept)."""
from __future__ import annotations

import sys
from pathlib import Path

from derive.codegen.files import REALS, generate_files
from derive.codegen.emit import write_tree
from derive.codegen.kernels import OBSERVER_STEPS, ParamsMode


def add_arguments(parser) -> None:
    """CLI: derive generate [ARM] [--out DIR] [--real double|float] [--params baked|runtime]
    [--observer explicit|implicit] [--regressor]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--out", default="generated",
                        help="parent folder; the arm's files go to OUT/<arm>/ (default: generated)")
    parser.add_argument("--real", choices=REALS, default="double", help="C real type (default double)")
    parser.add_argument("--params", choices=[m.value for m in ParamsMode], default="baked",
                        help="parameters folded into constants (baked) or read at run time")
    parser.add_argument("--observer", choices=OBSERVER_STEPS, default=None,
                        help="the observer's step: explicit (forward Euler of eq. 21) or implicit (backward Euler, "
                             "(J + dt W) y = ... solved numerically: no W J^-1 sample-time limit); default: the arm "
                             "file's controller.observer, else explicit")
    parser.add_argument("--regressor", action="store_true",
                        help="also write the identification regressor <arm>_regressor (C, Python, self-test): "
                             "J theta'' + G = Y pi in the base parameters pi (derive identify)")


def run(args) -> int:
    from derive.cli import report_warnings
    from derive.control.pipeline import derive
    from derive.cli import load_cli_arm
    from derive.codegen.files import GENERATE_STAGES
    from derive.control.ranges import check_ranges
    from derive.control.sampling.limit_text import summary, too_slow
    from derive.progress import progress

    arm = load_cli_arm(args)
    args.observer = args.observer or arm.controller.observer   # the arm file's step unless --observer
    with progress(total=2 + len(GENERATE_STAGES), desc=f"generate {arm.name}", unit="stage") as bar:
        bar.set_postfix_str("derivation")
        d = derive(arm)
        check_ranges(d, args.real)   # an arm the chosen real type cannot hold is refused before any warning
        bar.update()
        bar.set_postfix_str("sample-time limits")
        sentence = summary(d, args.observer)
        bar.update()

        started = 0

        def stage(name: str) -> None:
            nonlocal started
            bar.update(1 if started else 0)   # the previous stage is done
            started += 1
            bar.set_postfix_str(name)

        notes: list[str] = []
        files = generate_files(d, None, args.real, ParamsMode(args.params), notes,  # hash of the bytes load_arm read
                               sample_time=sentence, stage=stage, observer=args.observer, regressor=args.regressor)
        bar.update()
    report_warnings(d)
    for text in too_slow(d, arm.simulation.sample_time, observer=args.observer):
        print(f"derive: warning: simulation.sample_time of {arm.name}: {text}", file=sys.stderr)
    target = Path(args.out) / arm.name
    done = write_tree(target, files)   # only derive's previous files are replaced; sim/, build/ stay
    for note in notes:
        print(f"derive: warning: {note}", file=sys.stderr)
    kept = f" (kept what derive did not write: {', '.join(done.kept)})" if done.kept else ""
    print(f"derive: wrote {len(files)} files to {target}{kept}", file=sys.stderr)
    return 0
