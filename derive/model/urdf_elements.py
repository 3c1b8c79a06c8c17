"""What one URDF element gives a chain (derive.model.urdf): a joint's origin, axis, motion and limits,
a link's body, the <dynamics> values, and the notes on what reading them did."""
from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from typing import Any
import sympy as sp
from derive.model.chain import Body, Joint, Limits, Transform
from derive.model.fields import Reader
from derive.model.rigid import (NEAR_MISS, angle_note, snap_tolerance, axis_angle, body_from_com, empty_body, exact_angle,
                                rational, rational_unit, rpy)


_BODY_NAMES = ("m", "hx", "hy", "hz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
_INERTIA_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _joint_field(name: str, what: str = "") -> str:
    return f"urdf joint {name!r}" + (f" {what}" if what else "")


def _link_field(name: str, what: str = "") -> str:
    return f"urdf link {name!r}" + (f" {what}" if what else "")


def _angles(values: Any, where: str, log: list[tuple[str, str, str]] | None) -> list[sp.Expr]:
    """rpy angles, exact (:func:`derive.model.rigid.exact_angle`); what was snapped or kept near a
    multiple of pi/2 goes to ``log`` as (kind, text, where)."""
    out = []
    for x in values or (0, 0, 0):
        if log is not None and (note := angle_note(x)) is not None:
            log.append((note[0], note[1], where, note[2]))
        out.append(exact_angle(x))
    return out


def _origin(o: Any, where: str = "", log: list | None = None) -> Transform:
    """URDF <origin>: x_parent = R x_child + p (identity when absent); R rational
    (derive.model.rigid: snapped to k pi/2, else the nearest rational rotation)."""
    if o is None:
        return Transform.identity()
    xyz = [rational(x) for x in (o.xyz or (0, 0, 0))]
    return Transform(rpy(*_angles(o.rpy, where, log)), sp.ImmutableMatrix(xyz))


def _unit_axis(r: Reader, joint: Any, notes: list[str]) -> sp.ImmutableMatrix | None:
    raw = joint.axis if joint.axis is not None else (1.0, 0.0, 0.0)
    v = sp.Matrix([rational(x) for x in raw])
    norm2 = (v.T * v)[0, 0]
    if norm2 == 0:
        r.add(_joint_field(joint.name, "<axis xyz>"), "a non-zero axis (the joint moves about or along it)",
              " ".join(repr(float(x)) for x in raw))
        return None
    if norm2 != 1:
        unit = rational_unit(v)
        exact = sp.sqrt(norm2).is_Rational
        notes.append(f"joint {joint.name!r}: axis ({' '.join(f'{float(x):g}' for x in raw)}) is not unit length; "
                     f"normalised to ({', '.join(f'{float(x):.17g}' for x in unit)})"
                     + ("" if exact else " (the nearest rational unit vector, within 4e-18)"))
        return unit
    return sp.ImmutableMatrix(v)


def _motion(axis: sp.Matrix, kind: str, value: sp.Expr) -> Transform:
    if kind == "prismatic":
        return Transform(sp.ImmutableMatrix.eye(3), sp.ImmutableMatrix(axis * value))
    return Transform(axis_angle(axis, value), sp.ImmutableMatrix.zeros(3, 1))


def _link_body(link: Any, log: list | None = None) -> Body:
    """A link's <inertial> in its own frame (empty when absent)."""
    inertial = link.inertial
    if inertial is None:
        return empty_body()
    m = rational(inertial.mass if inertial.mass is not None else 0.0)
    t = inertial.inertia
    entries = [rational(getattr(t, k) or 0.0) if t is not None else sp.Integer(0)
               for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")]
    I = sp.Matrix(3, 3, lambda i, j: entries[_INERTIA_INDEX.index((min(i, j), max(i, j)))])
    o = inertial.origin
    com = sp.Matrix([rational(x) for x in (o.xyz if o is not None and o.xyz else (0, 0, 0))])
    R = rpy(*_angles(o.rpy if o is not None else None, f"link {link.name!r} <inertial><origin rpy>", log))
    return body_from_com(m, com, I, R)


_USE = {"damping": "the viscous friction bv (the default of motor.viscous_friction; G's damping term)",
        "friction": "the Coulomb friction in the simulation and the plant FMU (the default of "
                    "simulation.coulomb_friction), not part of the controller's model"}


def _dynamics(j: Any, key: str) -> Fraction | None:
    """``<dynamics damping|friction>`` of chain joint ``j`` (None: absent)."""
    x = getattr(j.dynamics, key, None) if j.dynamics is not None else None
    return None if x is None else Fraction(repr(float(x)))


def _dynamics_notes(joints: list[Joint], damping: list[Fraction], friction: list[Fraction | None],
                    notes: list[str]) -> None:
    """One note per kind: which joints' <dynamics damping|friction> are used, and how."""
    for key, values in (("damping", damping), ("friction", friction)):
        given = [f"{j.name!r} {float(x):g}" for j, x in zip(joints, values) if x is not None and (x or key == "friction")]
        if given:
            notes.append(f"<dynamics {key}> of joint{'s' if len(given) > 1 else ''} {', '.join(given)} "
                         f"{'are' if len(given) > 1 else 'is'} {_USE[key]}")


def _limits(j: Any, zero: dict[str, list[str]]) -> Limits:
    """The <limit> of chain joint ``j``; a velocity or effort of 0 is no limit (None), the URDF files'
    way of writing "none" (a joint that may not move or push could not be driven), and its joint is
    listed in ``zero`` under "velocity" or "effort" for the note (:func:`_zero_limit_notes`)."""
    lim = j.limit
    if lim is None:
        return Limits()

    def f(x: Any) -> Fraction | None:
        return None if x is None else Fraction(repr(float(x)))

    def rate(key: str) -> Fraction | None:
        x = f(getattr(lim, key))
        if x == 0:
            zero[key].append(repr(j.name))
            return None
        return x
    if j.type == "continuous":
        return Limits(velocity=rate("velocity"), effort=rate("effort"))
    return Limits(f(lim.lower), f(lim.upper), rate("velocity"), rate("effort"))


def _zero_limit_notes(zero: dict[str, list[str]], notes: list[str]) -> None:
    """One note per key: the joints whose <limit velocity|effort> of 0 was read as no limit."""
    for key, names in zero.items():
        if names:
            notes.append(f"<limit {key}=\"0\"> of joint{'s' if len(names) > 1 else ''} {', '.join(names)} read as "
                         f"no {key} limit (the same in every command)")


def snap_suggestion(kept: Sequence[float]) -> float:
    """The ``[arm] snap_angles`` [rad] that takes every near miss kept (``kept``: how far each is from its
    multiple of pi/2 [rad]) as that multiple: the 1-2-5 value at or above the farthest (NEAR_MISS at most;
    the tolerance in force when none is kept), as the file writes it (5e-06, not 5 x 1e-6 = 4.9999999999999996e-06:
    derive init's draft then reads the chain it read, kept by derive.model.urdf.urdf_chain)."""
    if not kept:
        return snap_tolerance()
    return next((v for v in (float(f"{m}e{e}") for e in range(-8, -2) for m in (1, 2, 5)) if v >= max(kept)), NEAR_MISS)


def angle_notes(log: list[tuple[str, str, str, float]]) -> list[str]:
    """One sentence for the angles snapped to multiples of pi/2 and one for the near misses kept (with
    the ``[arm] snap_angles`` that would take them: the 1-2-5 value at or above the farthest, derive.model.rigid)."""
    tol = snap_tolerance()
    suggest = snap_suggestion([off for kind, _, _, off in log if kind == "kept"])
    out = []
    for kind, head in (("snapped", f"angles within {tol:g} rad of a multiple of pi/2 snapped to it "
                                   "(exact 0 and +-1 in their rotations)"),
                       ("kept", f"angles near a multiple of pi/2 but more than {tol:g} rad from it, kept "
                                "as written (their rotations are the nearest rational rotations, within 4e-18, "
                                "dense: derive check's exact proofs cost several times more); if pi/2 is meant, "
                                "write the full double (1.5707963267948966) or set snap_angles = "
                                f"{suggest:g} under [arm]")):
        seen: dict[str, list[str]] = {}
        for k, text, where, _ in log:
            if k == kind:
                seen.setdefault(text, []).append(where)
        if seen:
            items = [f"{text} at {where[0]}" + (f" and {len(where) - 1} more" if len(where) > 1 else "")
                     for text, where in seen.items()]
            out.append(f"{head}: {'; '.join(items)}")
    return out


def _value(x: sp.Expr) -> Fraction:
    """An exact body value as a Fraction (rational: derive.model.rigid makes every rotation rational)."""
    x = sp.sympify(x)
    if not x.is_Rational:
        raise ValueError(f"a body parameter is not rational: {x}")
    return Fraction(int(x.p), int(x.q))
