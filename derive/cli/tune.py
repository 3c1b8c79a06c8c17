"""``derive tune [ARM] [--speed V1,V2,...] [--rate BETA] [--structure chen|full] [--json FILE]``:
the smallest observer gain W certified on a speed box at a rate (derive.control.certificate.synthesis).

Prints W, ||W||_2, the certificate's verdict and, when it is proved (exit 0), the ``w = ...`` line to
put in the arm file's [controller]; an unproven W gets no such line and exit 1. The box is ``--speed`` or the arm's max_joint_speed; one of them is needed.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from derive import jsonio
from derive.errors import DeriveError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI: derive tune [ARM] [--speed ...] [--rate BETA] [--structure chen|full] [--json FILE]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--speed", default=None, metavar="V1,V2,...",
                        help="the speed box |theta'_k| <= V_k [rad/s] (default: the arm's max_joint_speed)")
    parser.add_argument("--rate", type=float, default=None,
                        help="exponential rate beta [1/s] the certificate must give (default: the arm's observer_rate or 0)")
    parser.add_argument("--structure", choices=("chen", "full"), default=None,
                        help="W[i][j] = w_j for j <= i (eq. 25, default) or a full matrix")
    parser.add_argument("--json", type=Path, default=None, help="also write the result as JSON to this file")


def _speeds(text: str, n: int) -> tuple[float, ...]:
    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) and v > 0 for v in values):
        raise DeriveError(f"--speed: expected {n} comma-separated finite numbers > 0 (rad/s), got {text!r}")
    return tuple(values)


def gain_unit(arm) -> str:
    """W's unit: p = W theta' is a joint torque whatever drives the joint (eq. 21 adds it to
    G - B u, and B dhat = z + p, eq. 22), so W is N m s/rad (N s/m on a prismatic joint's row):
    kg m^2/s, J's unit over time, and W J^-1 is a rate [1/s]."""
    kinds = {j.type.rotates for j in arm.chain.joints}
    if kinds == {True}:
        return "N m s/rad"
    return "N s/m" if kinds == {False} else "N m s/rad (N s/m on a prismatic joint's row)"


def run(args: argparse.Namespace) -> int:
    from derive.control.certificate.report import inertia_model
    from derive.control.pipeline import derive
    from derive.control.certificate.synthesis import synthesise
    from derive.cli import load_cli_arm
    from derive.codegen.emit import write_file as write_text

    arm = load_cli_arm(args)
    ctl = arm.controller
    if args.speed is not None:
        box = _speeds(args.speed, arm.n)
    elif ctl.max_joint_speed is not None:
        box = tuple(float(x) for x in ctl.max_joint_speed)
    else:
        raise DeriveError(f"derive tune {arm.name}: expected a speed box, from --speed or the arm's "
                          "controller.max_joint_speed; got neither")
    rate = float(ctl.observer_rate) if args.rate is None else args.rate
    if not (math.isfinite(rate) and rate >= 0):
        raise DeriveError(f"--rate: expected a finite number >= 0 (1/s), got {args.rate}")
    structure = args.structure or ctl.observer_structure
    if args.json is not None and not args.json.parent.is_dir():
        raise DeriveError(f"--json {args.json}: expected a file in an existing folder, got a missing folder "
                          f"{args.json.parent}")
    d = derive(arm)
    syn = synthesise(inertia_model(d), box, rate, structure)
    rows = [[float(x) for x in row] for row in syn.W]
    if structure == "chen":
        line = "w = [" + ", ".join(f"{rows[j][j]:g}" for j in range(arm.n)) + "]"
    else:
        line = "w = [" + ", ".join("[" + ", ".join(f"{x:g}" for x in row) + "]" for row in rows) + "]"
    unit = gain_unit(arm)
    out = [f"derive tune {arm.name}: box |theta'| <= [{', '.join(f'{v:g}' for v in box)}] rad/s, rate {rate:g} 1/s, "
           f"{structure} structure",
           f"W = {rows} {unit}, ||W||_2 = {syn.norm:.6g}",
           f"certificate: {syn.decision.verdict.value} ({syn.decision.cells} cells; program headroom {syn.headroom:g}, "
           f"{syn.rounds} solves, {syn.samples} constraints, {syn.seconds:.1f} s)"]
    proved = syn.decision.verdict.value == "proved"
    if proved:
        out.append(f"[controller] {line}")
    else:   # exit 1: nothing to paste (issue 34 item 1: it printed a gain to paste and exited 1)
        out.append(f"no [controller] line to paste: this W is {syn.decision.verdict.value} on the box, so derive "
                   "check would not certify it; keep the arm file's w (derive check states its decision), lower "
                   "--speed, or pass --structure full")
    sys.stdout.write("\n".join(out) + "\n")
    if args.json is not None:
        doc = {"arm": arm.name, "box_rad_per_s": list(box), "rate_per_s": rate, "structure": structure,
               "W": rows, "W_unit": unit, "norm": syn.norm, "certificate": syn.decision.verdict.value, "cells": syn.decision.cells,
               "headroom": syn.headroom, "seconds": round(syn.seconds, 3)}
        write_text(args.json, jsonio.dumps(doc, sort_keys=False))
    return 0 if proved else 1
