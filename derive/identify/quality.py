"""Is the identification good enough to write? The checks of derive identify, each a finding
a user can act on.

Two kinds. A *warning* is printed (``derive: warning: ...``) and, with ``--strict``, is an
error; a *refusal* keeps the arm file from being written unless ``--force`` (the report is
written either way). The rules and their thresholds:

=======================  ===========================================================  =========
finding                  when                                                         kind
=======================  ===========================================================  =========
solver accuracy          the LMI solve ended short of its tolerances                  refusal
                         (derive.identify.consistent: ``optimal_inaccurate``)
torque explained         the consistent estimate explains less than MIN_EXPLAINED     refusal
                         of the torque, |residual|^2 over |torque|^2 of all joints
joint explained          ... of one joint's torque                                    warning
condition number         cond of the stacked regressor above MAX_CONDITION            warning
relative std             a base parameter's relative standard deviation above         warning
                         MAX_RELATIVE_STD % (the motion hardly excites it)
angles out of range      a revolute joint's angles beyond its range by more than      warning
                         RANGE_SLACK of it (degrees written as radians?)
speeds                   a joint's speed above SPEED_FACTOR x its velocity limit      warning
                         (degrees? rpm?)
exact zeros kept         ZERO_SHARE or more of a joint's kept torques exactly 0       warning
                         (brake phases or dropouts: --exclude brake,zeros)
plausible bodies         an identified mass, or inertia about the centre of mass      warning
                         (its trace), more than PLAUSIBLE x off the arm file's
Coulomb friction         a joint moving one way only (derive.identify.run)            note
=======================  ===========================================================  =========

A time column in milliseconds shows as a sample rate 1000 times too low: the cut-off
check of derive.identify.signals names it. Several findings point at a unit mistake at
once (a log in degrees: angles of 176 "rad", speeds 30 x the limit, a fit that explains 5 %
of the torque, a condition number of 7,554); each message says which.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from derive.identify.run import Identification

MIN_EXPLAINED = 0.5        # share of the torque the written model must explain
MAX_CONDITION = 1e3        # of the stacked regressor (SI units)
MAX_RELATIVE_STD = 100.0   # % of a base parameter
RANGE_SLACK = 0.1          # of a joint's range (and 0.1 rad) beyond it
SPEED_FACTOR = 5.0         # x the joint's velocity limit
ZERO_SHARE = 0.01          # of a joint's kept torque values exactly 0
PLAUSIBLE = 3.0            # x off the arm file's mass or inertia
UNITS = "degrees written as radians, or a time column in milliseconds"


@dataclass(frozen=True)
class Finding:
    """One finding: ``kind`` ("refusal", "warning" or "note"), ``rule`` (a short name), text."""

    kind: str
    rule: str
    text: str


def findings(idn: Identification) -> list[Finding]:
    """Every finding of the module docstring's table for ``idn``, in the table's order."""
    out: list[Finding] = []
    if not idn.cons.accurate:
        out.append(Finding("refusal", "solver accuracy", f"the physically consistent estimate ended "
                           f"{idn.cons.status}: {idn.cons.words}"))
    explained = idn.explained(idn.predicted_cons)
    use = idn.samples.use
    y2 = (np.where(use, idn.samples.y, 0.0) ** 2).sum(axis=0)
    total = 1.0 - float(((1 - explained) * y2).sum() / max(float(y2.sum()), 1e-300))
    if total < MIN_EXPLAINED:
        out.append(Finding("refusal", "torque explained", f"the identified model explains {100 * total:.1f} % of the "
                           f"logged torque (at least {100 * MIN_EXPLAINED:.0f} % expected; residual RMS "
                           + ", ".join(f"{x:.3g}" for x in idn.rms(idn.predicted_cons)) + " N m against RMS torques "
                           + ", ".join(f"{x:.3g}" for x in np.sqrt(y2 / np.maximum(use.sum(axis=0), 1))) + "): a log "
                           f"in other units ({UNITS}, a torque in another unit), another joint order or sign, or "
                           "samples that are not the joint torque (--exclude)"))
    low = [j for j in range(idn.reg.n) if explained[j] < MIN_EXPLAINED]
    if low and total >= MIN_EXPLAINED:
        out.append(Finding("warning", "joint explained", "the identified model explains only "
                           + ", ".join(f"{100 * max(explained[j], 0):.0f} % of joint {j + 1}'s" for j in low)
                           + f" torque (at least {100 * MIN_EXPLAINED:.0f} % expected): noise, friction the model "
                           "lacks (--coulomb), or samples that are not the joint torque"))
    if idn.ls.cond > MAX_CONDITION:
        out.append(Finding("warning", "condition number", f"the condition number of the stacked regressor is "
                           f"{idn.ls.cond:.3g} (at most {MAX_CONDITION:.0f} expected): the logged motion excites "
                           "some base parameters far less than others (a richer motion: derive excite), or the "
                           f"log is in other units ({UNITS})"))
    rel = idn.ls.relative_std
    bad = [k for k in range(len(rel)) if np.isfinite(rel[k]) and rel[k] > MAX_RELATIVE_STD]
    if bad:
        worst = max(bad, key=lambda k: rel[k])
        out.append(Finding("warning", "relative std", f"{len(bad)} of {len(rel)} base parameters have a relative "
                           f"standard deviation above {MAX_RELATIVE_STD:.0f} % (the largest: {idn.names[worst]} "
                           f"{rel[worst]:.3g} %): the logged motion hardly excites them, so their written values "
                           "come from the prior (the report's tables; a richer motion: derive excite)"))
    units = _units(idn)
    out += units + _zeros(idn) + _bodies(idn, bool(units))
    for j, why in sorted(idn.friction_refused.items()):
        out.append(Finding("note", "Coulomb friction", f"fc{j} is not identified (held at 0): {why}; --force "
                           "identifies it anyway"))
    return out


def _units(idn: Identification) -> list[Finding]:
    """Angles beyond a joint's range, speeds far above its limit: a log in degrees (one
    finding each, naming every joint)."""
    s, arm = idn.samples, idn.arm
    speeds = arm.controller.max_joint_speed or ()
    angles, fast = [], []
    for j, joint in enumerate(arm.chain.joints):
        rows = s.use[:, j]
        if not rows.any() or not joint.type.rotates:
            continue
        lo, hi = joint.limits.lower, joint.limits.upper
        q = s.theta[rows, j]
        if lo is not None and hi is not None:
            slack = RANGE_SLACK * float(hi - lo) + 0.1
            top, bottom = float(q.max()), float(q.min())
            if top > float(hi) + slack or bottom < float(lo) - slack:
                angles.append(f"joint {j + 1} from {bottom:.4g} to {top:.4g} rad (its range {float(lo):.4g} ... "
                              f"{float(hi):.4g})")
        limits = [float(v) for v in (joint.limits.velocity, speeds[j] if j < len(speeds) else None)
                  if v is not None and v > 0]
        if limits:
            top = float(np.abs(s.dtheta[rows, j]).max())
            if top > SPEED_FACTOR * min(limits):
                fast.append(f"joint {j + 1} up to {top:.4g} rad/s ({top / min(limits):.0f} x its limit "
                            f"{min(limits):.4g})")
    out = []
    if angles:
        out.append(Finding("warning", "angles out of range", "angles beyond the joint's range in the log: "
                           + "; ".join(angles) + ": degrees written as radians? (theta must be in rad)"))
    if fast:
        out.append(Finding("warning", "speeds", f"speeds above {SPEED_FACTOR:g} x the joint's velocity limit in the "
                           "log: " + "; ".join(fast) + ": degrees written as radians (or rpm)?"))
    return out


def _zeros(idn: Identification) -> list[Finding]:
    """Torques exactly 0 that no rule excluded."""
    out = []
    for run in idn.samples.runs:
        kept = run.removed.get("kept_torques")
        zeros = run.removed.get("kept_zeros")
        if not kept or not zeros:
            continue
        joints = [j for j, (z, k) in enumerate(zip(zeros, kept)) if k and z >= ZERO_SHARE * k]
        if joints:
            out.append(Finding("warning", "exact zeros kept", f"{run.source}: "
                               + ", ".join(f"{100 * zeros[j] / kept[j]:.0f} % of joint {j + 1}'s" for j in joints)
                               + " torque values are exactly 0 and used: brake phases or dropouts? (--exclude brake "
                               "for samples where every torque is 0, --exclude zeros for each 0)"))
    if len(out) > 3:
        out = out[:2] + [Finding("warning", "exact zeros kept", f"... and {len(out) - 2} more logs with exact zeros")]
    return out


def _bodies(idn: Identification, units: bool) -> list[Finding]:
    """Each body whose identified mass or inertia about its centre of mass is PLAUSIBLE x off
    the arm file's, named, with whether the data determines it (``units``: a unit finding
    explains it)."""
    out = []
    for i in range(idn.reg.n):
        prior, got = idn.phi0[10 * i: 10 * i + 10], idn.cons.phi[10 * i: 10 * i + 10]
        idx = [k for k, b in enumerate(idn.model.body) if b == i + 1]     # m first; the inertia entries last
        shares = (idn.share[idx[:1]], idn.share[idx[4:] if len(idx) == 10 else idx[2:]])
        parts, seen = [], []
        for what, a, b, unit, share in (("mass", prior[0], got[0], "kg", shares[0]),
                                        ("inertia about its centre of mass (trace)", _central(prior), _central(got),
                                         "kg m^2", shares[1])):
            if a <= 0 or not math.isfinite(b) or 1 / PLAUSIBLE <= b / a <= PLAUSIBLE:
                continue
            parts.append(f"{what} {b:.4g} {unit}, {b / a:.3g} x the arm file's {a:.4g}")
            seen.append(float(np.nanmax(share)) if share.size and np.isfinite(share).any() else 0.0)
        if not parts:
            continue
        if units:
            why = "the log's units (above) explain it"
        elif max(seen) >= 0.5:
            why = (f"the data determines it (a share of {max(seen):.2f} of what is known of it): the logged torque may "
                   "not be the whole joint torque (a drive that compensates gravity), or not in SI units")
        else:
            why = (f"the data sees it only in combination with other parameters (a share of {max(seen):.2f} of what is "
                   "known of it) and moved it with them: the logged torque may not be the whole joint torque, or "
                   "the file leaves out a load (a payload, a tool); a smaller --prior-uncertainty holds it nearer "
                   "the file")
        out.append(Finding("warning", "plausible bodies", f"body {i + 1} (moved by '{idn.arm.chain.joints[i].name}'): "
                           f"identified " + " and ".join(parts) + f" (more than {PLAUSIBLE:g} x off); {why}"))
    return out


def _central(b: np.ndarray) -> float:
    """tr of a body's inertia about its centre of mass, from its ten parameters."""
    m, h = b[0], b[1:4]
    trace = b[4] + b[7] + b[9]
    return float(trace - 2 * (h @ h) / m) if m > 0 else float(trace)
