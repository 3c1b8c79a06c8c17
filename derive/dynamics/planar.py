"""The planar arm's own forms: the paper's lumped 2-link form (a6) and an
independent planar Euler-Lagrange reference.

* :func:`lumped_2link`: j1, j2, j3, X of eq. (a6), read off J of a planar
  2-link chain and checked to have exactly that form;
* :func:`planar_reference`: the Euler-Lagrange equations of a planar arm
  file written in the plane (positions of each link and point mass as sums of
  l cos, l sin of absolute angles), a second reference beside the chain's
  (:func:`derive.dynamics.equations.lagrange_reference`) that shares no code
  with the chain model.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import sympy as sp

from derive.dynamics.identities import matrix_is_zero
from derive.model.actuators import terms
from derive.model.spec import Arm
from derive.model.symbols import JointSymbols

if TYPE_CHECKING:
    from derive.dynamics.equations import Dynamics


@dataclass(frozen=True)
class Body:
    """Planar rigid body in its link frame (origin at its joint, x along the link)."""

    M: sp.Expr   # total mass
    hx: sp.Expr  # first moment of mass along x (M times the centre-of-mass distance)
    Io: sp.Expr  # moment of inertia about the joint


@dataclass(frozen=True)
class PlanarSymbols:
    """The planar arm file's quantities in the arm's parameter symbols, read by
    field (``link[i].length``, ``point_mass[k].mass``, ...); a default the file
    left out is the expression it stands for (com = l/2, a uniform rod's
    I_c = m l^2/12, a point mass without inertia 0). Per link: length, mass,
    com, inertia; per point mass: its link (0-based), mass, distance, inertia."""

    links: tuple[tuple[sp.Expr, sp.Expr, sp.Expr, sp.Expr], ...]
    point_masses: tuple[tuple[int, sp.Expr, sp.Expr, sp.Expr], ...]
    g: sp.Symbol

    @staticmethod
    def of(arm: Arm) -> "PlanarSymbols":
        by = {p.field: p.symbol for p in arm.chain.parameters}
        links = []
        for i in range(1, arm.n + 1):
            l, m = by[f"link[{i}].length"], by[f"link[{i}].mass"]
            links.append((l, m, by.get(f"link[{i}].com", l / 2), by.get(f"link[{i}].inertia", m * l ** 2 / 12)))
        pms = tuple((pm.link, by[f"point_mass[{k}].mass"], by[f"point_mass[{k}].distance"],
                     by.get(f"point_mass[{k}].inertia", sp.Integer(0)))
                    for k, pm in enumerate(arm.point_masses, 1))
        return PlanarSymbols(tuple(links), pms, by["arm.gravity"])


def lumped_bodies(arm: Arm) -> tuple[Body, ...]:
    """(M, hx, Io) of each link with the point masses it carries."""
    p = PlanarSymbols.of(arm)
    bodies = []
    for i, (l, m, c, Ic) in enumerate(p.links):
        M, hx, Io = m, m * c, Ic + m * c ** 2
        for link, mp, rp, Ip in p.point_masses:
            if link == i:
                M += mp
                hx += mp * rp
                Io += Ip + mp * rp ** 2
        bodies.append(Body(M, hx, Io))
    return tuple(bodies)


def _down(arm: Arm) -> tuple[sp.Expr, sp.Expr]:
    """The unit direction of free fall in the base plane (arm.gravity_direction, normalised)."""
    g = arm.chain.gravity
    symbol = next(p.symbol for p in arm.chain.parameters if p.field == "arm.gravity")
    return sp.expand(g[0] / symbol), sp.expand(g[1] / symbol)


def lagrange(arm: Arm, s: JointSymbols) -> tuple[sp.Matrix, sp.Matrix]:
    """Reference J and rigid G (Coriolis, centrifugal, gravity) from the Lagrangian.

    Kinetic energy of every link and point mass (translation of the centre of
    mass, rotation at the absolute angle rate) and potential energy g y.
    """
    n = arm.n
    p = PlanarSymbols.of(arm)
    q, dq = s.theta, s.dtheta
    phi = [sum(q[: i + 1]) for i in range(n)]
    joint = [(sp.Integer(0), sp.Integer(0))]
    for i, (l, _, _, _) in enumerate(p.links):
        x, y = joint[-1]
        joint.append((x + l * sp.cos(phi[i]), y + l * sp.sin(phi[i])))
    down = _down(arm)
    masses = [(m, i, c, Ic) for i, (_, m, c, Ic) in enumerate(p.links)]
    masses += [(mp, link, rp, Ip) for link, mp, rp, Ip in p.point_masses]
    T = V = sp.Integer(0)
    for m, i, r, inertia in masses:
        x = joint[i][0] + r * sp.cos(phi[i])
        y = joint[i][1] + r * sp.sin(phi[i])
        vx = sum(sp.diff(x, qj) * dqj for qj, dqj in zip(q, dq))
        vy = sum(sp.diff(y, qj) * dqj for qj, dqj in zip(q, dq))
        wi = sum(dq[: i + 1])
        T += m * (vx ** 2 + vy ** 2) / 2 + inertia * wi ** 2 / 2
        V -= m * p.g * (down[0] * x + down[1] * y)
    T += sum(terms(a)[2] * dq[i] ** 2 for i, a in enumerate(arm.actuators)) / 2
    dT = sp.Matrix([sp.diff(T, v) for v in dq])
    J = dT.jacobian(dq).applyfunc(sp.expand)
    G = dT.jacobian(q) * sp.Matrix(dq) - sp.Matrix([sp.diff(T - V, v) for v in q])
    return J, G.applyfunc(sp.expand)


def planar_reference(arm: Arm, dyn: Dynamics) -> tuple[sp.Matrix, sp.Matrix]:
    """(J, G) of the planar Euler-Lagrange equations of ``arm`` (a [[link]] arm
    file), in the symbols of ``dyn`` (its dynamics): expanded, n x n and n x 1."""
    J, G_rigid = lagrange(arm, dyn.sym)
    return J, G_rigid + dyn.damping * sp.Matrix(dyn.sym.dtheta)


def lumped_2link(dyn: Dynamics) -> dict[str, sp.Expr]:
    """The paper's inertial parameters j1, j2, j3, X of eq. (a6), for n = 2.

    Read off J at theta2 = pi/2 and 0, then J is checked to have exactly the
    form [[j1 + 2X cos t2, j2 + X cos t2], [j2 + X cos t2, j3]]; a DerivationError
    otherwise.
    """
    from derive.errors import DerivationError

    t2 = dyn.sym.theta[1]
    J = dyn.J
    at = {t2: sp.pi / 2}
    lumped = {"j1": J[0, 0].subs(at), "j2": J[0, 1].subs(at), "j3": J[1, 1].subs(at),
              "X": sp.expand(J[0, 1].subs(t2, 0) - J[0, 1].subs(at))}
    if not matrix_is_zero(J - a6_form(lumped, t2), dyn.sym.theta):
        raise DerivationError("the 2-link inertia matrix does not have the form (a6)")
    return {k: sp.expand(v) for k, v in lumped.items()}


def a6_form(lumped: dict[str, sp.Expr], theta2: sp.Symbol) -> sp.Matrix:
    """J(theta) of eq. (a6) from j1, j2, j3, X."""
    c = sp.cos(theta2)
    j1, j2, j3, X = (lumped[k] for k in ("j1", "j2", "j3", "X"))
    return sp.Matrix([[j1 + 2 * X * c, j2 + X * c], [j2 + X * c, j3]])
