"""``derive identify [ARM] LOG [LOG ...] --out identified.toml``: identified parameters from logged runs.

Reads each log (derive.identify.log: t, theta1..n, one of tau/current/u 1..n, optional
dtheta1..n and valid; a shell-style glob given as one argument is expanded), keeps the
samples the ``--exclude`` rules leave (derive.identify.exclude), filters and
differentiates each log on its own (zero-phase, ``--cutoff`` Hz), stacks the regression
of every log, solves weighted least squares of the base parameters (with standard
deviations) and the physically consistent estimate of the standard parameters (LMIs,
cvxpy with Clarabel) with the arm file as its prior (``--prior-uncertainty``), judges the
result (derive.identify.quality), then writes the report folder (``--report``, default
<out>_report/: identification.md, identification.json, torques.png, parameters.png) and
the arm file with the identified values (derive.identify.armfile). Warnings are errors
with ``--strict``; a refusal (the solver short of its accuracy, a fit that explains too
little of the torque) writes the report but not the arm file, unless ``--force``. Nothing
is written when the logs cannot give the parameters.
Then ``derive generate identified.toml`` regenerates the controller.
With ``--payload`` only the payload on the last body is identified (derive.cli.identify_payload).
"""
from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from derive import jsonio
from derive.errors import DataError

if TYPE_CHECKING:
    from derive.identify.run import Identification


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI: derive identify [ARM] LOG [LOG ...] [--out FILE] [--report DIR] [--cutoff HZ] [--coulomb]
    [--exclude RULES] [--prior-uncertainty R] [--payload LOG ...] [--force] [--strict]."""
    from derive.cli import add_arm_argument
    from derive.identify import CUTOFF
    from derive.identify.prior import PRIOR_UNCERTAINTY

    add_arm_argument(parser)
    parser.add_argument("logs", nargs="*", metavar="LOG",
                        help="the logged runs (CSV: t, theta1..n, tau1..n | current1..n | u1..n, optional dtheta1..n "
                             "and valid); a glob in quotes ('runs/*.csv') is expanded")
    parser.add_argument("--out", type=Path, default=None,
                        help="the identified arm file (default <arm>_identified.toml; --payload: <arm>_payload.toml)")
    parser.add_argument("--report", type=Path, default=None, help="the report folder (default <out>_report)")
    parser.add_argument("--cutoff", type=float, default=CUTOFF,
                        help=f"cut-off of the zero-phase low-pass filter [Hz] (default {CUTOFF:g})")
    parser.add_argument("--coulomb", action="store_true",
                        help="also identify a Coulomb friction fc sign(theta') per joint (reported only: the "
                             "controller's model has none); not on a joint that moves one way only, unless --force")
    parser.add_argument("--exclude", action="append", metavar="RULES",
                        help="leave out samples that are not the joint torque (repeat, or comma-separated): brake "
                             "(every torque exactly 0), zeros (a torque exactly 0), saturated (a torque at its "
                             "limit), ends=MS (the first and last MS ms of each log)")
    parser.add_argument("--prior-uncertainty", type=float, default=PRIOR_UNCERTAINTY, metavar="R",
                        help="how well the arm file's masses, centres of mass and inertias are known, relative (one "
                             f"standard deviation; default {PRIOR_UNCERTAINTY:g}): what the data does not see stays "
                             "at the file's values")
    parser.add_argument("--payload", nargs="+", metavar="LOG", default=None,
                        help="identify from these logs only the payload on the last body (mass, centre of mass, "
                             "inertia about it; the rest is the arm file's) and write it into [payload]; with "
                             "--coulomb also each moving joint's viscous and Coulomb friction (reported only)")
    parser.add_argument("--force", action="store_true",
                        help="write the arm file although the solver fell short of its accuracy or the fit explains "
                             "too little of the torque; identify Coulomb friction on one-signed joints")


def run(args: argparse.Namespace) -> int:
    if args.payload is not None:
        from derive.cli.identify_payload import run as run_payload
        return run_payload(args)
    if not args.logs and not (args.arm is not None and str(args.arm).lower().endswith(".csv")):
        raise DataError("identify: expected at least one LOG (a CSV file of a logged run) after the arm file")
    from derive.cli import load_cli_arm
    from derive.codegen.emit import write_file, write_tree
    from derive.identify.armfile import identified_text
    from derive.identify.exclude import parse_exclude
    from derive.identify.log import log_paths, read_log
    from derive.identify.quality import findings
    from derive.identify.report import parameter_figure, report_data, report_json, report_markdown, torque_figure
    from derive.identify.armfile import outputs
    from derive.identify.run import identify

    rules = parse_exclude(args.exclude)
    R = args.prior_uncertainty
    if not (R > 0 and R < 1e6):
        raise DataError(f"--prior-uncertainty {R:g}: expected a relative standard deviation > 0 (0.5: the file's "
                        "masses and inertias right to 50 %)")
    if args.arm is not None and str(args.arm).lower().endswith(".csv"):     # no ARM: the default arm's logs
        args.logs, args.arm = [args.arm] + list(args.logs), None
    paths = log_paths(args.logs)
    arm = load_cli_arm(args)
    logs = [read_log(p, arm.n) for p in paths]
    source, out, report = outputs(args.arm, args.out, args.report, arm, "identified")
    idn = identify(arm, logs, args.cutoff, args.coulomb, rules=rules, uncertainty=R, force=args.force)
    found = findings(idn)
    blocking = [f for f in found if f.kind == "refusal" and not args.force]
    blocking += [f for f in found if f.kind == "warning" and args.strict]
    names = ", ".join(p.name for p in paths[:3]) + (f", ... ({len(paths)} logs)" if len(paths) > 3 else "")
    text = None if blocking else identified_text(idn, source.read_text(encoding="utf-8-sig"), source, out, names)
    data = report_data(idn, [log.source for log in logs], out.name if text is not None else None, found)
    files = {"identification.md": report_markdown(data), "identification.json": report_json(data)}
    pngs = {"torques.png": torque_figure(idn), "parameters.png": parameter_figure(idn)}
    listing = {k: hashlib.sha256(v.encode() if isinstance(v, str) else v).hexdigest()
               for k, v in sorted({**files, **pngs}.items())}
    files["MANIFEST.json"] = jsonio.dumps({"_note": "generated by derive identify; do not edit", "files": listing})
    for f in found:
        if f.kind != "refusal":
            print(f"derive: {f.kind}: {f.text}", file=sys.stderr)
    write_tree(report, files, pngs)
    print(summary(idn, data))
    if blocking:
        why = "; ".join(f"{f.rule}: {f.text}" if f.kind == "refusal" else f"{f.rule} (--strict)" for f in blocking)
        raise DataError(f"identify: {out} not written ({why}); the report is in {report}/"
                        + ("" if all(f.kind == "warning" for f in blocking) else "; --force writes it anyway"))
    write_file(out, text)
    print(f"derive: wrote {out} and {report}/ (then: derive generate {out})", file=sys.stderr)
    return 0


def summary(idn: "Identification", data: dict) -> str:
    """The lines derive identify prints: rows, condition number, torque explained, the worst
    relative standard deviation, the solver."""
    import numpy as np

    rel = idn.ls.relative_std
    worst = max(range(len(idn.names)), key=lambda k: rel[k] if np.isfinite(rel[k]) else -1.0)
    runs = data["logs"]
    lines = [f"{idn.arm.name}: {len(idn.names)} base parameters from {data['rows']['equations']} equations of "
             f"{len(runs)} log{'s' if len(runs) > 1 else ''}, condition number {idn.ls.cond:.4g}; torque explained "
             "per joint: " + ", ".join(f"{100 * j['explained_consistent']:.1f} %" for j in data["joints"]),
             f"largest relative standard deviation: {idn.names[worst]} {rel[worst]:.3g} %; consistent estimate: "
             f"{idn.cons.status} ({idn.cons.iterations} iterations), smallest scaled LMI eigenvalue "
             f"{min(idn.cons.min_eigenvalues):.3g}"]
    return "\n".join(lines)
