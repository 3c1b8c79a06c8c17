"""The pipeline: arm -> dynamics -> mpc -> observer -> npid = one frozen Derivation.

Every stage works in parameter symbols (masses, lengths, motor constants,
gains k1, k2, w); the Derivation also carries the matrices with the arm's exact
values put in, which is what users and the tests read.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import sympy as sp

from derive.dynamics.dag import Substitution, matrix_xreplace
from derive.dynamics.equations import Dynamics, derive_dynamics
from derive.dynamics.planar import lumped_2link
from derive.control.mpc import Mpc, derive_mpc, gains
from derive.control.momentum import Momentum, by_recursion, derive_momentum
from derive.control.npid import Npid, derive_npid
from derive.control.observer import Observer, derive_observer, speed_bound
from derive.control.sampling.grid import check_definite
from derive.control.opaque import OpaqueDynamics
from derive.control.ranges import check_ranges
from derive.control.sampling.wrap import wrap, wrapped_outputs
from derive.model.spec import Arm, momentum_parameters
from derive.summary import compact_repr

if TYPE_CHECKING:   # imported where w = "auto" needs it: the SDP synthesis and its certificate (~10 ms)
    from derive.control.certificate.synthesis import Synthesis


@compact_repr
@dataclass(frozen=True)
class Derivation:
    """The single intermediate representation of an arm's controller.

    Numeric (arm values put in, exact rationals) SymPy matrices, n joints:
    J (n x n, eq. 12), G (n x 1), B (n x n), K1, K2 (n x n, eq. 16-17),
    W (n x n, eq. 25), L (n x n, eq. 24; an unevaluated W J^-1 for n > 2),
    P, D, I (n x n, eq. 35-37), N (n x 1, eq. 38), dhat0 (n x 1, the derived
    initial estimate in e0_i, de0_i), u_star (eq. 15), u_dobc (eq. 27),
    u_npid (eq. 34), dhat (eq. 22). ``lumped``: j1, j2, j3, X of eq. (a6) for
    n = 2, else None; ``speed_bound``: w1/X, the largest theta2' for which
    (26) holds (n = 2, else None); ``warnings``: sentences for the user (e.g. a
    stated maximum speed above that bound). ``dynamics``, ``mpc``, ``observer``, ``npid``
    hold the same in symbols; ``values`` maps every symbol to its value.
    """

    arm: Arm
    dynamics: Dynamics
    mpc: Mpc
    observer: Observer
    npid: Npid
    values: tuple[tuple[sp.Symbol, sp.Rational], ...]
    theta: tuple[sp.Symbol, ...]
    dtheta: tuple[sp.Symbol, ...]
    J: sp.Matrix
    G: sp.Matrix
    B: sp.Matrix
    C: sp.Matrix
    K1: sp.Matrix
    K2: sp.Matrix
    W: sp.Matrix
    L: object
    P: sp.Matrix
    D: sp.Matrix
    I: sp.Matrix
    N: sp.Matrix
    dhat0: sp.Matrix
    u_star: sp.Matrix
    u_dobc: sp.Matrix
    u_npid: sp.Matrix
    dhat: sp.Matrix
    lumped: dict | None
    speed_bound: sp.Expr | None
    warnings: tuple[str, ...]
    synthesis: Synthesis | None = None   # the W chosen for w = "auto" (derive.control.certificate.synthesis)
    momentum: Momentum | None = None     # the generalized-momentum observer (derive.control.momentum), symbols
    u_mom: sp.Matrix | None = None       # eq. 27 with its estimate: u* - B^-1 K (J theta' - m), numeric
    wrapped: tuple[int, ...] = ()        # outputs whose error is wrapped to (-pi, pi] (derive.control.sampling.wrap)
    formal: "Derivation | None" = None  # the same over placeholders J, G, g, C (derive.control.opaque)

    @property
    def n(self) -> int:
        return len(self.theta)

    @property
    def formal_view(self) -> "Derivation | None":
        """The Derivation over placeholders this one was inlined from (derive.control.opaque),
        or None: a copy made with dataclasses.replace (a field changed) has none, since its
        matrices are no longer the inlining of the formal ones."""
        mark = self.__dict__.get("_formal_of")
        return mark if mark is not None and mark is self.formal else None

    @property
    def k_formulas(self) -> tuple[sp.Expr, sp.Expr]:
        """k1, k2 in the symbols T1, T2 (eq. 16-18)."""
        return gains()

    @cached_property
    def _put_values(self) -> Substitution:
        return Substitution(dict(self.values), keep_sums=True)

    @cached_property
    def _put_measurements(self) -> Substitution:
        s = self.dynamics.sym
        e, de = self.tracking_error
        return Substitution(keep_sums=True, rule={**dict(zip(s.e, e)), **dict(zip(s.de, de)),
                             **dict(zip(s.e0, e)), **dict(zip(s.de0, de))})

    def numeric(self, expr):
        """``expr`` (in parameter and gain symbols) with the arm's values put in."""
        return self._put_values(expr)

    @property
    def tracking_error(self) -> tuple[sp.Matrix, sp.Matrix]:
        """(e, e') in the measurements: e = yd - C theta (eq. 20), e' = yd' - C theta' (n x 1 each);
        the outputs of ``wrapped`` (those a continuous joint moves) have e wrapped to (-pi, pi]
        (derive.control.sampling.wrap), so theta and theta - 2 pi give the same e."""
        s = self.dynamics.sym
        e = sp.Matrix(s.yd) - self.C * sp.Matrix(s.theta)
        e = sp.Matrix([wrap(e[i]) if i in self.wrapped else e[i] for i in range(e.rows)])
        return e, sp.Matrix(s.dyd) - self.C * sp.Matrix(s.dtheta)

    def measured(self, expr):
        """``expr`` with e, e' and e(0), e'(0) written in the measurements (eq. 20);
        at the first sample e(0) and e'(0) are the current e and e'."""
        return self._put_measurements(expr)


def derive(arm: Arm) -> Derivation:
    """Derive the dynamics, predictive law, observer and PID form of ``arm``.

    Raises SpecError, naming the arm-file fields, when a derived constant is not a
    normal double (``derive.control.ranges``: e.g. T2 = 1e-170 makes k1 = 3e339), or when J(theta) is
    singular at a configuration within the joint limits (``derive.control.sampling.grid.check_definite``)."""
    dyn = derive_dynamics(arm)
    ctl = arm.controller
    # the control stages are algebra over J, G, g, C: built over placeholders (milliseconds),
    # then the dynamics put in (derive.control.opaque); the placeholder forms are what
    # derive check decides the control obligations on
    odyn = OpaqueDynamics(dyn)
    mpc_f = derive_mpc(odyn, ctl.T1, ctl.T2, ctl.C)
    wrapped = wrapped_outputs(mpc_f.Cout, dyn.chain.joints, arm.source)
    synthesis = None
    if ctl.w_auto:
        from derive.control.certificate.synthesis import synthesise_for

        synthesis = synthesise_for(arm, matrix_xreplace(dyn.J, dict(dyn.values)), dyn.sym.theta)
        chen = synthesis.structure == "chen"
        obs_f = derive_observer(odyn, w_values=[synthesis.W[j][j] for j in range(arm.n)] if chen else None,
                                W_values=None if chen else synthesis.W)
    else:
        obs_f = derive_observer(odyn, w_values=ctl.w, W_values=ctl.W)
    npid_f = derive_npid(odyn, mpc_f, obs_f)
    mom_f = derive_momentum(odyn)
    mpc, obs, npid, mom = (odyn.inline_stage(x) for x in (mpc_f, obs_f, npid_f, by_recursion(mom_f, odyn)))
    mom_values = tuple((p.symbol, p.rational) for p in momentum_parameters(ctl))
    values = dyn.values + mpc.values + obs.values + mom_values
    rep = dict(values)
    num = Substitution(rep, keep_sums=True)  # one memo for every matrix: they share J's and G's subexpressions

    lumped = bound = None
    if arm.n == 2 and dyn.chain.planar:   # the paper's lumped form (a6) is a planar 2-link one
        lumped = {k: v.xreplace(rep) for k, v in lumped_2link(dyn).items()}
        if not obs.full:
            bound = speed_bound(lumped["X"], rep[obs.w[0]]) if lumped["X"] != 0 else sp.oo
    warnings = []
    speeds = ctl.max_joint_speed
    if bound is not None and speeds is not None and sp.Rational(speeds[1].numerator, speeds[1].denominator) >= bound:
        warnings.append(
            f"controller.max_joint_speed[2] = {float(speeds[1]):g} rad/s is not below w1/X = "
            f"{float(bound):.6g} rad/s: condition (26) fails there, so theorem 2 does not "
            "guarantee that the observer converges at that speed (raise w1 or lower the speed)")
    d = Derivation(
        arm=arm, dynamics=dyn, mpc=mpc, observer=obs, npid=npid, values=values,
        theta=dyn.sym.theta, dtheta=dyn.sym.dtheta, J=num(dyn.J), G=num(dyn.G), B=num(dyn.B),
        C=mpc.Cout, K1=num(mpc.K1), K2=num(mpc.K2), W=num(obs.W), L=num(obs.L), P=num(npid.P),
        D=num(npid.D), I=num(npid.I), N=num(npid.N), dhat0=num(npid.dhat0).applyfunc(sp.expand),
        u_star=num(mpc.u_star),
        u_dobc=num(npid.u_dobc), u_npid=num(npid.u_npid), dhat=num(obs.dhat), lumped=lumped,
        speed_bound=bound, warnings=tuple(warnings), synthesis=synthesis, momentum=mom,
        u_mom=num(mpc.u_star - mom.dhat), wrapped=wrapped,
        formal=_formal(arm, odyn, mpc_f, obs_f, npid_f, mom_f, values, wrapped))
    # the pair is marked: only this Derivation, not a copy with fields replaced, is the
    # inlining of its formal one (derive.proofs.project.formal_first relies on it)
    object.__setattr__(d, "_formal_of", d.formal)
    check_ranges(d, "double")  # show, check, simulate and the Python module compute in double
    check_definite(d)          # J invertible within the joint limits (derive.control.sampling.grid), before any output
    return d


def _formal(arm: Arm, odyn: OpaqueDynamics, mpc: Mpc, obs: Observer, npid: Npid, mom: Momentum,
            values: tuple, wrapped: tuple[int, ...]) -> "Derivation":
    """The Derivation over placeholders (derive.control.opaque): J, G, g, C are symbol
    matrices, every law the same algebra over them, the arm's values put in."""
    num = Substitution(dict(values), keep_sums=True)
    return Derivation(
        arm=arm, dynamics=odyn, mpc=mpc, observer=obs, npid=npid, values=values, theta=odyn.sym.theta,
        dtheta=odyn.sym.dtheta, J=odyn.J, G=odyn.G, B=num(odyn.B), C=mpc.Cout, K1=num(mpc.K1), K2=num(mpc.K2),
        W=num(obs.W), L=num(obs.L), P=num(npid.P), D=num(npid.D), I=num(npid.I), N=num(npid.N),
        dhat0=num(npid.dhat0), u_star=num(mpc.u_star), u_dobc=num(npid.u_dobc), u_npid=num(npid.u_npid),
        dhat=num(obs.dhat), lumped=None, speed_bound=None, warnings=(), momentum=mom,
        u_mom=num(mpc.u_star - mom.dhat), wrapped=wrapped)
