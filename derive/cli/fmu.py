"""``derive fmu``: the controller of an arm as a co-simulation FMU (FMI 2.0 or 3.0)."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from derive.codegen.files import REALS
from derive.codegen.forms import DEFAULT_FORM, FORMS
from derive.codegen.kernels import ParamsMode


def add_arguments(parser) -> None:
    """CLI: derive fmu [ARM] [--fmi 2|3] [--form F] [--real R] [--params P] [--sample-time S]
    [--observer explicit|implicit] [--plant] [--out DIR] [--cc CC]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--fmi", default="3", help="FMI version, 2 or 3 (default 3)")
    parser.add_argument("--form", default=DEFAULT_FORM,
                        help=f"controller form, one of {', '.join(FORMS)} (default {DEFAULT_FORM})")
    parser.add_argument("--real", default="double", help=f"C real type, one of {', '.join(REALS)} (default double)")
    parser.add_argument("--params", default=ParamsMode.BAKED.value,
                        help="baked (constants) or runtime (tunable FMU parameters); default baked")
    parser.add_argument("--sample-time", type=float, default=None,
                        help="the FMU's default communication step = the controller's sample time [s] "
                             "(default: the arm file's simulation.sample_time)")
    parser.add_argument("--observer", default=None,
                        help="the observer step, as derive generate --observer: explicit (forward Euler) or implicit "
                             "(backward Euler: no observer limit on the sample time); default: the arm file's "
                             "controller.observer, else explicit")
    parser.add_argument("--out", default="fmu", help="folder the FMU is written to (default: fmu)")
    parser.add_argument("--plant", action="store_true",
                        help="also write <arm>_plant.fmu: the simulation plant of the arm's [simulation] section "
                             "with the reference, whose outputs wire to the controller's inputs")
    parser.add_argument("--cc", default=None, help="host C compiler for the binary (default: $CC or cc)")


def run(args) -> int:
    from derive.cli import report_warnings
    from derive.control.pipeline import derive
    from derive.fmu import check_options, controller_fmu, plant_fmu, write_fmus
    from derive.cli import load_cli_arm

    options = check_options(args.fmi, args.form, args.real, args.params, args.sample_time, args.observer or "explicit")
    out = Path(args.out)
    if out.exists() and not out.is_dir():  # before any work: one clear error, nothing written
        from derive.errors import EmitError
        raise EmitError(f"--out {out}: expected a folder, got a file")
    arm = load_cli_arm(args)
    if args.observer is None and arm.controller.observer != options.observer:   # the arm file's step
        options = check_options(args.fmi, args.form, args.real, args.params, args.sample_time, arm.controller.observer)
    d = derive(arm)
    report_warnings(d)
    cc = args.cc or os.environ.get("CC") or "cc"
    arm_bytes = Path(arm.source).read_bytes()
    fmus = dict([controller_fmu(d, options, cc, arm_bytes)])
    if args.plant:
        s = arm.simulation
        noisy = [k for k in ("velocity_noise", "position_noise") if any(getattr(s, k))]
        noisy += ["tacho_filter_hz"] if s.tacho_filter_hz > 0 else []
        if noisy:
            print(f"derive: warning: the plant FMU has no sensor noise and no tachometer filter; "
                  f"simulation.{', simulation.'.join(noisy)} of {arm.name} not included", file=sys.stderr)
        fmus.update([plant_fmu(d, options.fmi, cc, arm_bytes, options.sample_time)])
    for path in write_fmus(out, fmus):  # all built first: a failure writes nothing
        print(f"derive: wrote {path} (FMI {options.fmi}.0 co-simulation)", file=sys.stderr)
    return 0
