"""Obligations on the derived dynamics themselves (kind ``project``): J' - 2C skew, energy,
and the generated RNEA law equal to eq. (15)'s u*.

Each is decided exactly, never by sampling, in two kinds of steps:

* facts about the DAG that need no expansion (derive.proofs.structure): syntactic identity
  by value numbering (G is built as bias + F q'; the recursive Newton-Euler pass at a = 0
  *is* G; the kernels' law *is* that pass at a = C^-1 (K1 e + K2 e' + y_d'')), and the
  monomial structure (the pass is affine in a with no a q' product; the bias is affine in
  the gravity symbol with no g q' product);
* polynomial identities on the torus of the joint angles (derive.proofs.torus), split so
  that the costly rates appear only where they must: the a-coefficient of the pass against
  J's columns and gravity against g(q) in the angles alone, J' = C + C^T and
  1/2 q'^T J' q' = q'^T h(q, q') (h the velocity part of the bias) with the rates.

One ring per derivation, so J and the bias parts convert once for all obligations. A 7-joint
arm whose constant rotations are multiples of pi/2 takes a few seconds; one with rotations
such as 1.5708 (rationals of 120 bits, every product dense) tens of seconds. A polynomial
past ``LIMIT`` terms leaves the obligation ``unproven`` (said so), never guessed.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import flint
import sympy as sp

from derive.dynamics.dag import xreplace_all
from derive.proofs.core import Kind, Obligation, Outcome, Status, combine
from derive.proofs.structure import affine_apart, same
from derive.proofs.torus import TooLarge, Torus

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation

LIMIT = 2_000_000       # terms of one polynomial: the proofs' memory budget (about 1 GB at worst)
TOTAL = 10_000_000      # terms one conversion holds at once (snake12's Coriolis matrix: 5.6 million, under 8 million held)
_RINGS: dict = {}


class _Ring:
    """The derivation's torus ring with J, C, the velocity bias converted on first use."""

    def __init__(self, d: "Derivation") -> None:
        self.d = d
        s = d.dynamics.sym
        rotating = set(d.dynamics.angles)
        others = [q for q in d.theta if q not in rotating] + list(d.dtheta) + list(s.u)
        self.T = Torus(d.dynamics.angles, others, limit=LIMIT, total=TOTAL)
        self._cache: dict[str, list] = {}

    def get(self, key: str, make) -> list:
        if key not in self._cache:
            self._cache[key] = self.T.convert(list(make()))
            self.T.forget()         # the memo of intermediate polynomials: memory, not needed again
        return self._cache[key]

    @property
    def J(self) -> list:
        return self.get("J", lambda: self.d.J)

    def rates(self) -> dict:
        return {q: self.T.var(dq) for q, dq in zip(self.d.theta, self.d.dtheta)}


def ring(d: "Derivation") -> _Ring:
    """The shared ring of ``d`` (one per derivation object)."""
    hit = _RINGS.get(id(d))
    if hit is None or hit.d is not d:
        _RINGS.clear()          # one derivation at a time: the rings hold large polynomials
        hit = _RINGS[id(d)] = _Ring(d)
    return hit


def _budget(check):
    """``check`` with a polynomial past the budget reported as unproven (the reason named)."""
    def run(d: "Derivation") -> Outcome:
        try:
            return check(d)
        except TooLarge as exc:
            return Outcome(Status.UNPROVEN, f"not decided within the proofs' budget: {exc}")
    run.__doc__ = check.__doc__
    return run


def check_skew(d: "Derivation") -> Outcome:
    """J' - 2 C is skew-symmetric for the derived J and its Coriolis matrix C: J' = C + C^T,
    decided exactly on the torus of the angles with the rates."""
    R, n = ring(d), d.n
    T = R.T
    C = T.convert(list(d.numeric(d.dynamics.coriolis)))   # not kept: no other obligation needs C (12 joints: 5.6M terms)
    T.forget()
    rates = R.rates()
    for i in range(n):
        for j in range(i, n):
            if not T.is_zero(T.d_dt(R.J[i * n + j], rates) - C[i * n + j] - C[j * n + i]):
                return Outcome(Status.REFUTED, f"J' - 2C is not skew-symmetric: J'[{i + 1}][{j + 1}] differs from "
                               f"(C + C^T)[{i + 1}][{j + 1}] (the canonical remainder is not zero)")
    return Outcome(Status.PROVED, f"N = J' - 2C satisfies N + N^T = 0 (n = {n}, J' = C + C^T decided exactly on the "
                   "torus of the angles)")


def _gravity_symbol(d: "Derivation") -> sp.Symbol | None:
    found = set().union(*(sp.sympify(x).free_symbols for x in d.dynamics.chain.gravity))
    return next(iter(found)) if len(found) == 1 else None


def check_energy(d: "Derivation") -> Outcome:
    """d/dt (1/2 theta'^T J theta') = theta'^T (B u - G_nc) along (12), d = 0, with G_nc = g(theta)
    + F theta' (the part of G that does work); J = J^T; g is a gradient."""
    R, n, dyn = ring(d), d.n, d.dynamics
    T = R.T
    J = R.J
    parts = []
    sym = all(T.is_zero(J[i * n + j] - J[j * n + i]) for i in range(n) for j in range(i + 1, n))
    parts.append(Outcome(Status.PROVED, "J = J^T") if sym else Outcome(Status.REFUTED, "J is not symmetric"))
    # G = bias + F q' (syntactic), bias = h(q, q') + g(q): affine in the gravity symbol with no
    # g q' product, the bias at g = 0 is h (syntactic), the bias at q' = 0 is g(q) (exact, angles only)
    dq = list(d.dtheta)
    gs = _gravity_symbol(d)
    split = same(list(dyn.G), list(dyn.bias + dyn.damping * sp.Matrix(dq)))
    if gs is not None:
        split = split and affine_apart(list(dyn.bias), [gs], dq) and same(
            xreplace_all(dyn.bias, {gs: sp.Integer(0)}, keep_sums=True), list(dyn.velocity_bias))
        at_rest = xreplace_all(d.numeric(dyn.bias), {v: sp.Integer(0) for v in dq}, keep_sums=True)
        grav = d.numeric(dyn.gravity)
        split = split and all(T.is_zero(T(a) - T(b)) for a, b in zip(at_rest, grav))
    else:
        split = split and same(list(dyn.bias), list(dyn.velocity_bias)) and all(x == 0 for x in dyn.gravity)
    if not split:
        parts.append(Outcome(Status.UNPROVEN, "G is not seen to be h(q, q') + g(q) + F q' (the structure the energy "
                             "balance is decided on)"))
        return combine(parts)
    h = R.get("h", lambda: d.numeric(dyn.velocity_bias))
    rates = R.rates()
    qd = [T.var(x) for x in dq]
    # with J theta'' = B u - G and G = h + g + F theta': dT/dt - theta'^T (B u - g - F theta')
    # = 1/2 theta'^T J' theta' - theta'^T h
    residual = -sum((qd[i] * h[i] for i in range(n)), T.zero)
    for i in range(n):
        for j in range(n):
            residual = residual + T.d_dt(J[i * n + j], rates) * qd[i] * qd[j] * flint.fmpq(1, 2)
    parts.append(Outcome(Status.PROVED, f"d/dt (1/2 theta'^T J theta') = theta'^T (B u - g(theta) - F_v theta') "
                                        f"(n = {n})") if T.is_zero(residual) else
                 Outcome(Status.REFUTED, "the energy identity fails: C theta' + the velocity terms are not workless"))
    g = [T(x) for x in d.numeric(dyn.gravity)]
    grad = all(T.is_zero(T.diff(g[i], d.theta[j]) - T.diff(g[j], d.theta[i])) for i in range(n) for j in range(i + 1, n))
    parts.append(Outcome(Status.PROVED, "g(theta) is a gradient (d g/d theta symmetric)") if grad else
                 Outcome(Status.REFUTED, "g(theta) is not a gradient"))
    return combine(parts, summary=f"d/dt (1/2 theta'^T J theta') = theta'^T (B u - g - F_v theta') (n = {n})")


def check_rnea_law(d: "Derivation") -> Outcome:
    """The law the kernels compute, u* = B^-1 RNEA(theta, theta', a) at a = C^-1 (K1 e + K2 e' +
    yd'') (derive.control.mpc.u_star_rnea, one recursive Newton-Euler pass), is eq. (15)'s
    u* = B^-1 (J a + G)."""
    dyn, mpc, n = d.dynamics, d.mpc, d.n
    s = dyn.sym
    a = [sp.Symbol(f"_a{i + 1}", real=True) for i in range(n)]
    Rn = dyn.inverse_dynamics(a)
    e, de, ddyd = sp.Matrix(s.e), sp.Matrix(s.de), sp.Matrix(s.ddyd)
    aexpr = mpc.Cout.inv() * (mpc.K1 * e + mpc.K2 * de + ddyd)
    Binv = [1 / dyn.B[i, i] for i in range(n)]
    law = [b * x for b, x in zip(Binv, xreplace_all(Rn, dict(zip(a, aexpr)), keep_sums=True))]
    steps = [("the generated law is B^-1 RNEA(theta, theta', a) at a = C^-1 (K1 e + K2 e' + yd'')",
              same(law, list(mpc.u_star_rnea))),
             ("RNEA is affine in a, with no a theta' product", affine_apart(list(Rn), a, list(d.dtheta))),
             ("RNEA at a = 0 is G", same(xreplace_all(Rn, {v: sp.Integer(0) for v in a}, keep_sums=True),
                                          list(dyn.G)))]
    if not all(ok for _, ok in steps):       # not the structure built by derive: decide the identity whole
        return _whole_rnea_law(d)
    # the a-coefficient, at theta' = 0 (it has no theta'): d RNEA(q, 0, a) / d a_j = J e_j, one
    # conversion with the a_j as variables of their own ring (the law is affine in them)
    rotating = set(d.dynamics.angles)
    T = Torus(d.dynamics.angles, [q for q in d.theta if q not in rotating] + a, limit=LIMIT, total=TOTAL)
    num = d.numeric(Rn)
    rest = {v: sp.Integer(0) for v in d.dtheta}
    rows = T.convert(xreplace_all(num, rest, keep_sums=True))
    J = T.convert(list(d.J))
    for i in range(n):
        for j in range(n):
            if not T.is_zero(T.diff(rows[i], a[j]) - J[i * n + j]):
                return Outcome(Status.REFUTED, f"the RNEA law differs from eq. (15): its coefficient of a{j + 1} in "
                               f"row {i + 1} is not J[{i + 1}][{j + 1}]")
    # and eq. (15)'s u* is B^-1 (J a + G) in the placeholders it is inlined from
    f = d.formal_view
    if f is not None:
        want = sp.diag(*Binv) * (f.J * f.mpc.Cout.inv() * (f.K1 * e + f.K2 * de + ddyd) + f.G)
        if any(sp.expand(x - y) != 0 for x, y in zip(f.u_star, want.applyfunc(d.numeric))):
            return Outcome(Status.REFUTED, "eq. (15)'s u* is not B^-1 (J a + G)")
    else:
        return Outcome(Status.UNPROVEN, "not decided: this Derivation is not the inlining of its placeholder form")
    return Outcome(Status.PROVED, f"B^-1 RNEA(theta, theta', a) = B^-1 (J a + G) = u* of (15) (n = {n}): the "
                   "generated law is the derived one (the pass is affine in a, equals G at a = 0 and J in a, exactly)")


def _whole_rnea_law(d: "Derivation") -> Outcome:
    """The RNEA law against eq. (15) expanded whole on the torus (the law's structure unseen)."""
    law = d.numeric(d.mpc.u_star_rnea)
    s = d.dynamics.sym
    rotating = set(d.dynamics.angles)
    others = [q for q in d.theta if q not in rotating] + list(d.dtheta) + list(s.e) + list(s.de) + list(s.ddyd)
    T = Torus(d.dynamics.angles, others, limit=LIMIT, total=TOTAL)
    for i, (x, y) in enumerate(zip(T.convert(list(law)), T.convert(list(d.u_star)))):
        if not T.is_zero(x - y):
            return Outcome(Status.REFUTED, f"the RNEA law differs from eq. (15) in u*[{i + 1}] (expanded whole)")
    return Outcome(Status.PROVED, f"B^-1 RNEA(theta, theta', a) = B^-1 (J a + G) = u* of (15) (n = {d.n}), expanded "
                   "whole: the generated law is the derived one")


OBLIGATIONS = (
    Obligation("skew-symmetry", "eq. 12", Kind.PROJECT, "J' - 2C is skew-symmetric", _budget(check_skew)),
    Obligation("energy", "eq. 12", Kind.PROJECT, "d/dt (1/2 theta'^T J theta') = theta'^T (B u - G_nc)",
               _budget(check_energy)),
    Obligation("rnea-law", "eq. 15", Kind.PROJECT,
               "the generated law (one RNEA pass) equals u* of (15): RNEA(theta, theta', a) = J a + G",
               _budget(check_rnea_law)),
)
