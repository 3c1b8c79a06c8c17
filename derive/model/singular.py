"""Which joint of a chain moves no inertia at all (then J(q) is singular everywhere).

For a serial chain, J_ii(q) = a_i^T I_i(q) a_i + r_i for a revolute joint and
M_i + r_i for a prismatic one, where I_i(q) is the composite inertia of bodies
i..n about joint i's origin (in F_i), a_i its axis, M_i the total mass of
bodies i..n and r_i the reflected rotor inertia gr_i^2 Jm_i. Each body adds a
non-negative amount, so J_ii is zero at every configuration exactly when joint
i moves nothing: then e_i^T J e_i = 0 and J is singular for every q. Massless
bodies elsewhere are fine (URDF and Drake accept them) as long as every joint
moves some inertia.

Decided exactly from the parameter values: J_ii at q = 0 in exact arithmetic
(zero there: J(0) is singular, refused); then, for the message, whether
J_ii(q) is zero at every configuration, as a trigonometric polynomial in the
joints beyond i that is identically zero iff its numerator vanishes after the
substitution
cos q = (1 - t^2) / (1 + t^2), sin q = 2 t / (1 + t^2). (J can still be
singular at some configurations with every J_ii > 0, e.g. a massless first
link carrying a point mass on a two-link arm stretched out: a kinematic
singularity, which the dynamics' numeric check reports.)
"""
from __future__ import annotations

from dataclasses import replace

import sympy as sp

from derive.model.chain import Body, Chain, JointType, Transform
from derive.model.rigid import axis_angle, merge, move


def joint_motion(chain: Chain, j: int, q: sp.Expr) -> Transform:
    """F_{j-1} <- F_j (0-based j) at joint value q: origin * Rot(axis, q) or origin * Trans(axis q)."""
    joint = chain.joints[j]
    if joint.type is JointType.PRISMATIC:
        motion = Transform(sp.ImmutableMatrix.eye(3), sp.ImmutableMatrix(joint.axis * q))
    else:
        motion = Transform(axis_angle(joint.axis, q), sp.ImmutableMatrix.zeros(3, 1))
    return joint.origin.compose(motion)


def axial_inertia(chain: Chain, i: int, reflected: sp.Expr, values: dict, q: list[sp.Expr],
                  digits: int | None = None) -> sp.Expr:
    """J_ii at joint values ``q`` with the parameter ``values`` put in; exact, or in
    ``digits``-digit floats (origins with cos/sin of decimal angles swell when expanded exactly)."""
    return axial_inertias(chain, [reflected if k == i else 0 for k in range(chain.n)], values, q, digits, i)[i]


def axial_inertias(chain: Chain, reflected: list, values: dict, q: list[sp.Expr], digits: int | None = None,
                   first: int = 0) -> dict[int, sp.Expr]:
    """J_ii for every joint i >= ``first`` (as :func:`axial_inertia`), the composite bodies built once
    from the tip (each joint's is the next one's moved and merged with its own body: O(n), where
    building each from the tip again was O(n^2) merges of 50-digit matrices)."""
    def num(x):
        x = x.xreplace(values)
        return x.evalf(digits) if digits else x
    if digits:
        chain = Chain(tuple(replace(j, origin=Transform(num(j.origin.R), num(j.origin.p)), axis=num(j.axis))
                            for j in chain.joints), chain.bodies, chain.gravity, chain.parameters)
    bodies = [Body(num(sp.sympify(b.mass)), num(b.first_moment), num(b.inertia)) for b in chain.bodies]
    out, total = {}, bodies[-1]
    for i in range(len(bodies) - 1, first - 1, -1):
        if i < len(bodies) - 1:
            total = merge(bodies[i], move(total, joint_motion(chain, i + 1, q[i + 1])))
        a = sp.Matrix(chain.joints[i].axis)
        moved = total.mass if chain.joints[i].type is JointType.PRISMATIC else (a.T * total.inertia * a)[0, 0]
        out[i] = sp.expand(moved + num(sp.sympify(reflected[i])))
    return out


def _identically_zero(expr: sp.Expr, angles: list[sp.Symbol]) -> bool:
    rep = {}
    for a in angles:
        t = sp.Dummy("t")
        rep[sp.cos(a)] = (1 - t ** 2) / (1 + t ** 2)
        rep[sp.sin(a)] = 2 * t / (1 + t ** 2)
    num, _ = sp.fraction(sp.together(sp.expand_trig(expr).xreplace(rep)))
    return sp.expand(num) == 0


def _is_zero(x: sp.Expr) -> bool:
    if x.is_Rational:
        return x == 0
    return abs(sp.N(x, 50)) < sp.Float("1e-40")


def unmoved_joint(chain: Chain, reflected: list[sp.Expr],
                  values: dict[sp.Symbol, sp.Expr] | None = None) -> tuple[int, bool] | None:
    """The first joint (0-based) with J_ii = 0 at q = 0, and whether J_ii = 0 at
    every configuration (it moves nothing) or only there; None when every
    J_ii(0) > 0. Either way J(0) is singular (e_i^T J e_i = 0).

    ``reflected``: r_i = gr_i^2 Jm_i per joint (parameter expressions);
    ``values``: every parameter's value (default: the chain's).
    """
    values = chain.values() if values is None else values
    n = chain.n
    zero = [sp.Integer(0)] * n
    scale = 1 + sum(abs(float(sp.sympify(b.mass).xreplace(values))) for b in chain.bodies)
    rough = axial_inertias(chain, reflected, values, zero, 50)
    for i in range(n):
        # 50 digits decide every J_ii(0) clearly away from 0; exact arithmetic the rest
        if abs(rough[i]) > 1e-30 * scale:
            continue
        if not _is_zero(axial_inertia(chain, i, reflected[i], values, zero)):
            continue
        angles = [sp.Symbol(f"q{j + 1}", real=True) for j in range(n)]
        everywhere = _identically_zero(axial_inertia(chain, i, reflected[i], values, angles),
                                       [a for j, a in enumerate(angles) if chain.joints[j].type.rotates])
        return i, everywhere
    return None
