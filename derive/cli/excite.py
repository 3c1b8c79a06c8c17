"""``derive excite [ARM] --duration T --out traj.csv``: an excitation trajectory for identification.

A finite Fourier series per joint (Swevers et al. 1997; derive.identify.excite), starting
and ending at rest, optimised for the condition number of the stacked regressor within the
joints' position, velocity and acceleration limits (the URDF's, the arm file's
max_joint_speed, the options, else stated defaults), written as CSV (t, theta1..n,
dtheta1..n, ddtheta1..n) at ``--rate`` Hz. Prints the limits with their sources, the peaks
reached and the condition number. Deterministic for a ``--seed``.

With ``--payload`` (derive identify --payload): only the wrist (the last WRIST joints) moves, the
other joints held at ``--hold`` (default: the middle of each range), and the coefficients
minimise the condition number of the payload's ten regressor columns (derive.identify.payload).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from derive import jsonio
from derive.errors import DataError

WRIST = 3     # joints excited by derive excite --payload: the last three


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI: derive excite [ARM] --duration T --out FILE [--harmonics L] [--seed S] [--iterations K]
    [--rate HZ] [--velocity-limit V] [--acceleration-limit A] [--payload [--hold Q]] [--json FILE]."""
    from derive.cli import add_arm_argument
    from derive.identify import HARMONICS

    add_arm_argument(parser)
    parser.add_argument("--duration", type=float, required=True, help="length of the trajectory [s]")
    parser.add_argument("--out", type=Path, required=True, help="the CSV file to write")
    parser.add_argument("--harmonics", type=int, default=HARMONICS, help=f"harmonics per joint (default {HARMONICS})")
    parser.add_argument("--seed", type=int, default=1, help="seed of the optimiser's start (default 1)")
    parser.add_argument("--iterations", type=int, default=100, help="optimiser iterations (default 100)")
    parser.add_argument("--rate", type=float, default=1000.0, help="sample rate of the CSV [Hz] (default 1000)")
    parser.add_argument("--velocity-limit", default=None, metavar="V[,V2,...]",
                        help="joint speed limits [rad/s or m/s], one for all or one per joint")
    parser.add_argument("--acceleration-limit", default=None, metavar="A[,A2,...]",
                        help="joint acceleration limits [rad/s^2 or m/s^2], one for all or one per joint "
                             "(default 5 rad/s^2, 2 m/s^2: URDF gives none)")
    parser.add_argument("--payload", action="store_true",
                        help=f"an excitation for derive identify --payload: only the last {WRIST} joints move, "
                             "optimised for the payload's ten parameters")
    parser.add_argument("--hold", default=None, metavar="Q[,Q2,...]",
                        help="with --payload: the positions [rad or m] the other joints are held at, one for all or "
                             "one per held joint (default: the middle of each range)")
    parser.add_argument("--json", type=Path, default=None, help="also write the coefficients, limits and "
                                                                "condition number as JSON to this file")


def per_joint(text: str | None, n: int, option: str) -> tuple[float, ...] | None:
    """One number for every joint, or n comma-separated numbers; DataError otherwise."""
    if text is None:
        return None
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) == 1:
        values *= n
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise DataError(f"{option}: expected one finite number or {n} comma-separated ones, got {text!r}")
    return tuple(values)


def summary(ex, n: int) -> list[str]:
    lines = [f"period {ex.period:g} s x {ex.repeats}, {ex.harmonics} harmonics, {len(ex.times())} samples at "
             f"{ex.rate:g} Hz; condition number of the stacked regressor {ex.cond:.4g}",
             "joint  position range (limit)              |speed| (limit)       |acceleration| (limit)"]
    for i, (lim, (lo, hi, v, a)) in enumerate(zip(ex.limits, ex.peaks()), 1):
        u = lim.unit
        lines.append(f"{i:5d}  [{lo:+.3f}, {hi:+.3f}] ([{lim.lower:+.3f}, {lim.upper:+.3f}]) {u}  "
                     f"{v:.3f} ({lim.velocity:g}) {u}/s  {a:.3f} ({lim.acceleration:g}) {u}/s^2")
    lines += [f"joint {i} limits from: {', '.join(lim.sources)}" for i, lim in enumerate(ex.limits, 1)]
    return lines


def run(args: argparse.Namespace) -> int:
    from derive.cli import load_cli_arm
    from derive.codegen.emit import write_file
    from derive.identify.excite import csv_text, excitation_limits, optimise
    from derive.identify.regressor import derive_regressor

    arm = load_cli_arm(args)
    n = arm.n
    limits = excitation_limits(arm.chain, arm.controller.max_joint_speed,
                               per_joint(args.velocity_limit, n, "--velocity-limit"),
                               per_joint(args.acceleration_limit, n, "--acceleration-limit"))
    if args.iterations < 0:
        raise DataError(f"--iterations: expected a number >= 0, got {args.iterations}")
    held = None
    if args.payload:
        from derive.identify.payload import check_arm, payload_regressor
        check_arm(arm)
        count = max(n - WRIST, 0)
        hold = per_joint(args.hold, count, "--hold") if args.hold is not None and count else None
        held = {j: hold[j] if hold else (limits[j].lower + limits[j].upper) / 2 for j in range(count)}
        bad = [f"joint {j + 1}: {q:g} outside [{limits[j].lower:g}, {limits[j].upper:g}]"
               for j, q in held.items() if not limits[j].lower <= q <= limits[j].upper]
        if bad:
            raise DataError("--hold: expected positions within the joints' ranges, got " + "; ".join(bad))
        reg = payload_regressor(arm.chain)
    elif args.hold is not None:
        raise DataError("--hold: expected with --payload only (the other excitations move every joint)")
    else:
        reg = derive_regressor(arm.chain)
    ex = optimise(reg, limits, args.duration, args.harmonics, args.seed, args.iterations, args.rate, held)
    text = csv_text(ex)
    data = None
    if args.json is not None:
        data = jsonio.dumps(jsonio.plain({
            "_note": "generated by derive excite; do not edit", "arm": arm.name, "period_s": ex.period,
            "repeats": ex.repeats, "harmonics": ex.harmonics, "seed": ex.seed, "rate_hz": ex.rate,
            "condition_number": ex.cond, "base_parameters": list(reg.names),
            "held": {str(j + 1): q for j, q in (held or {}).items()},
            "q0": ex.q0.tolist(), "a": ex.a.tolist(), "b": ex.b.tolist(),
            "limits": [{"joint": lim.name, "unit": lim.unit, "lower": lim.lower, "upper": lim.upper,
                        "velocity": lim.velocity, "acceleration": lim.acceleration,
                        "sources": list(lim.sources)} for lim in ex.limits]}))
    write_file(args.out, text)
    if data is not None:
        write_file(args.json, data)
    for line in summary(ex, n):
        print(line)
    print(f"derive: wrote {args.out} ({len(ex.times())} rows: t, theta1..{n}, dtheta1..{n}, ddtheta1..{n})",
          file=sys.stderr)
    return 0
