"""derive identify --payload: the ten inertial parameters of a payload on the last body from logged runs.

Everything of the arm but the payload is known (the arm file's values). The torque of eq. 12's
left side of the arm carrying a payload is (derive.dynamics.payload)

    J(q) q'' + G(q, q') + J_p(q) q'' + G_p(q, q') = tau,

and the payload's share is linear in its *standard* parameters in F_n (the last moving joint's
frame): mass m [kg], first moment h = m c [kg m], inertia about F_n's origin I_o [kg m^2]
(xx, xy, xz, yy, yz, zz),

    tau - (J q'' + G)_file = Y_n(q, q', q'') pi_p,   pi_p = (m, hx, hy, hz, Ixx, ..., Izz),

Y_n (n x 10) the last body's ten columns of the standard regressor: the Jacobian with respect to
pi_p of the recursive Newton-Euler torque of the chain whose bodies are all massless but the last
(derive.dynamics.rnea, the recursion of derive.identify.regressor). With ``coulomb``, each joint
that moves both ways adds a correction dfv_j of the file's viscous friction (q'_j on row j) and a
Coulomb friction fc_j (sign(q'_j), filtered as the torque) as nuisance parameters.

The logs are read, masked, filtered, differentiated and decimated as derive identify does
(derive.identify.signals); the rows of every joint are stacked (the static joints' torques carry
the payload's wrench too: a wrist-only motion determines all ten, Atkeson, An, Hollerbach,
IJRR 5(3), 1986), and weighted least squares (derive.identify.estimate) gives pi_p and its
covariance s^2 (W^T W)^-1. When the ten are not excited (the scaled regressor rank deficient),
(:func:`excitation` below UNEXCITED: a joint-6-only motion never shows Ixx, Iyy, Ixy), the payload
is taken as a point mass plus the file's inertia shape, and m, h alone are estimated (the
inertia's share, small, iterated to a fixed point). :mod:`derive.identify.payload_file`
converts the estimate to mass, centre of mass and inertia about it in the tip link's frame with
their standard deviations and writes the ``[payload]`` table.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np
import sympy as sp
from threadpoolctl import threadpool_limits

from derive.dynamics.crba import Composite, body_composite
from derive.dynamics.dag import jacobian
from derive.dynamics.equations import frames
from derive.dynamics.rnea import rnea
from derive.dynamics.spatial import ZERO, ZERO_VEC, vec
from derive.errors import DataError
from derive.identify import CUTOFF
from derive.identify.batch import Batch
from derive.identify.estimate import LeastSquares, least_squares
from derive.identify.exclude import Exclusion, mask
from derive.identify.log import Log
from derive.identify.parameters import BODY_UNITS, INERTIA_INDEX
from derive.identify.regressor import kinematics, sx_function
from derive.identify.run import one_signed
from derive.identify.signals import Samples, prepare
from derive.model.actuators import terms
from derive.model.chain import Chain
from derive.model.spec import Arm
from derive.model.symbols import JointSymbols

NAMES = ("m", "hx", "hy", "hz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")   # the payload's standard parameters
FIXED_POINT = 20      # iterations of the point-mass estimate (m, h with the inertia's share fixed)
LENGTH = 0.1          # m: a payload's size, scaling its columns (1, L, L^2: kg, kg m, kg m^2) for the rank test
UNEXCITED = 1e-6      # the scaled columns' smallest singular value below this share of the largest: not excited


@dataclass(frozen=True)
class PayloadRegressor:
    """Y_n (n x 10) of a payload on the last body of an n-joint chain and the file's torque
    J q'' + G (n) at the same states (module docstring), over ``sym``'s theta, dtheta, ddtheta.
    Duck-types derive.identify.regressor.Regressor for derive excite (``n``, ``p``, ``names``,
    :meth:`evaluate`)."""

    n: int
    sym: JointSymbols
    Y: sp.Matrix
    nominal: sp.Matrix
    seconds: float = field(default=0.0, compare=False)

    p = 10
    names = tuple(f"payload {k}" for k in NAMES)
    units = BODY_UNITS

    @cached_property
    def batch(self) -> Batch:
        """x = (theta, dtheta, ddtheta) (3n, points) -> [Y row-major (10 n, points), nominal (n, points)]."""
        x = ca.SX.sym("x", 3 * self.n)
        y = sx_function(self.sym, list(self.Y), "payload_regressor")(x)
        t = sx_function(self.sym, list(self.nominal), "nominal_torque")(x)
        return Batch(ca.Function("payload", [x], [y, t], ["x"], ["Y", "tau"], {"cse": True}))

    def _run(self, theta, dtheta, ddtheta) -> list[np.ndarray]:
        x = np.hstack([np.atleast_2d(theta), np.atleast_2d(dtheta), np.atleast_2d(ddtheta)]).T
        return self.batch(x)

    def evaluate(self, theta: np.ndarray, dtheta: np.ndarray, ddtheta: np.ndarray) -> np.ndarray:
        """Y_n at N states (each argument N x n): an array N x n x 10."""
        return self._run(theta, dtheta, ddtheta)[0].T.reshape(-1, self.n, self.p)

    def torques(self, theta: np.ndarray, dtheta: np.ndarray, ddtheta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Y_n: N x n x 10, the file's J q'' + G: N x n) at N states."""
        Y, tau = self._run(theta, dtheta, ddtheta)
        return Y.T.reshape(-1, self.n, self.p), tau.T


def payload_regressor(chain: Chain) -> PayloadRegressor:
    """The payload regressor of ``chain`` and its nominal torque, the arm file's values put in."""
    started = time.perf_counter()
    n, values = chain.n, chain.values()
    kin = kinematics(chain)
    sym = JointSymbols.make(n)
    fr = frames(kin, sym.theta)
    g = vec(kin.gravity)
    slots = [sp.Symbol(f"_payload_{k}", real=True) for k in NAMES]
    inertia = tuple(tuple(slots[4 + INERTIA_INDEX.index((min(a, b), max(a, b)))] for b in range(3)) for a in range(3))
    empty = Composite(ZERO, ZERO_VEC, (ZERO_VEC,) * 3)
    bodies = [empty] * (n - 1) + [Composite(slots[0], tuple(slots[1:4]), inertia)]
    Y = jacobian(rnea(bodies, fr, sym.dtheta, list(sym.ddtheta), g), slots)
    own = []
    for b in chain.bodies:
        c = body_composite(b)
        own.append(Composite(c.M.xreplace(values), vec([x.xreplace(values) for x in c.h]),
                             tuple(vec([x.xreplace(values) for x in row]) for row in c.I)))
    tau = rnea(own, fr, sym.dtheta, list(sym.ddtheta), g)
    motor = [terms(a) for a in chain.actuators]
    nominal = sp.Matrix([tau[j] + sp.sympify(motor[j][2]).xreplace(values) * sym.ddtheta[j]
                         + sp.sympify(motor[j][1]).xreplace(values) * sym.dtheta[j] for j in range(n)])
    return PayloadRegressor(n=n, sym=sym, Y=Y, nominal=nominal, seconds=time.perf_counter() - started)


@dataclass(frozen=True)
class PayloadFit:
    """The payload's estimate: ``pi`` (10: m, h, I_o in F_n), its covariance (10 x 10; zero rows
    and columns for I_o when ``inertia_excited`` is False: then I_o = Ic_shape + point mass, not
    estimated), the friction estimates (``friction_names``, values, standard deviations), the
    least squares (every column estimated), the joints refused a friction {joint (1-based): why},
    the samples, the RMS residual per joint before (the file's torque) and after [N m]."""

    pi: np.ndarray
    cov: np.ndarray
    inertia_excited: bool
    ls: LeastSquares
    names: tuple[str, ...]
    friction_names: tuple[str, ...]
    friction: np.ndarray
    friction_std: np.ndarray
    refused: dict
    samples: Samples
    rms_file: np.ndarray
    rms_fit: np.ndarray
    cond: float
    seconds: dict = field(default_factory=dict)


def _rms(res: np.ndarray, use: np.ndarray) -> np.ndarray:
    r = np.where(use, res, 0.0)
    return np.sqrt((r ** 2).sum(axis=0) / np.maximum(use.sum(axis=0), 1))


def _point_mass_io(m: float, h: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """The six I_o entries (INERTIA_INDEX order) of a payload of mass m, first moment h and
    inertia ``shape`` about its centre of mass (F_n axes)."""
    Io = shape + ((h @ h) * np.eye(3) - np.outer(h, h)) / m if m > 0 else shape
    return np.array([Io[a, b] for a, b in INERTIA_INDEX])


def excitation(Y: np.ndarray) -> float:
    """s_min / s_max of the payload's columns (rows x 10) scaled to a payload of 1 kg and LENGTH
    (kg, kg m, kg m^2 columns times 1, L, L^2): how well the motion excites all ten (0: some
    combination not at all; an inertia entry that the motion never turns about, say)."""
    scaled = Y * np.array([1.0] + [LENGTH] * 3 + [LENGTH ** 2] * 6)
    if scaled.shape[0] > 20:
        scaled = np.linalg.qr(scaled, mode="r")
    s = np.linalg.svd(scaled, compute_uv=False)
    return float(s[-1] / s[0]) if s[0] > 0 else 0.0


def check_arm(arm: Arm) -> None:
    """DataError for an arm whose payload cannot be identified here: a planar ``[[link]]`` arm
    (its payload moves in the plane: the out-of-plane centre of mass and most of the inertia
    never act; derive identify estimates the last link's planar parameters)."""
    if arm.spatial is None:
        raise DataError(f"identify --payload: {arm.name} is a planar [[link]] arm: expected a URDF, DH or MJCF arm "
                        "(a payload moving in the plane never shows its out-of-plane centre of mass or most of its "
                        "inertia); identify the last link with derive identify (without --payload) instead")


def identify_payload(arm: Arm, logs: Log | list[Log], cutoff: float = CUTOFF, coulomb: bool = False,
                     rules: Exclusion = Exclusion(), force: bool = False, shape: np.ndarray | None = None,
                     reg: PayloadRegressor | None = None) -> PayloadFit:
    """The payload of ``arm`` from ``logs`` (module docstring). ``shape``: the inertia about the
    centre of mass per kg (3 x 3, F_n axes) assumed when the inertia is not excited (None: a
    5 cm solid sphere). DataError for an arm :func:`check_arm` refuses, logs that leave too few
    equations, or a motion that does not excite the payload's mass and centre of mass (named)."""
    check_arm(arm)
    logs = [logs] if isinstance(logs, Log) else list(logs)
    with threadpool_limits(1, "blas"):
        return _identify(arm, logs, cutoff, coulomb, rules, force,
                         np.eye(3) * 0.4 * 0.05 ** 2 if shape is None else np.asarray(shape, float), reg)


def _identify(arm: Arm, logs: list[Log], cutoff: float, coulomb: bool, rules: Exclusion, force: bool,
              shape: np.ndarray, reg: PayloadRegressor | None) -> PayloadFit:
    seconds = {}
    mark = time.perf_counter()
    reg = payload_regressor(arm.chain) if reg is None else reg
    seconds["regressor"] = time.perf_counter() - mark
    n = arm.n
    families = {log.family for log in logs}
    if len(families) > 1:
        raise DataError(f"{logs[0].source}, ...: expected every log to hold the same signal, got "
                        + " and ".join(f"{f}1..{n}" for f in sorted(families)))
    mark = time.perf_counter()
    s = Samples.stack([prepare(log, arm.chain, cutoff, mask(log, rules, arm.motors)) for log in logs])
    seconds["filter"] = time.perf_counter() - mark
    refused = one_signed(s, n) if coulomb else {}
    friction = tuple(j for j in range(n) if coulomb and (force or j + 1 not in refused))
    fnames = tuple(f"dfv{j + 1}" for j in friction) + tuple(f"fc{j + 1}" for j in friction)
    where = logs[0].source if len(logs) == 1 else f"{len(logs)} logs ({logs[0].source}, ...)"
    mark = time.perf_counter()
    Yp, tau0 = reg.torques(s.theta, s.dtheta, s.ddtheta)                        # N x n x 10, N x n
    N = len(s.t)
    F = np.zeros((N, n, 2 * len(friction)))
    for k, j in enumerate(friction):
        F[:, j, k] = s.dtheta[:, j]
        F[:, j, len(friction) + k] = s.sign[:, j]
    seconds["regressor_rows"] = time.perf_counter() - mark
    y = s.y - tau0
    use, joint = s.use, np.nonzero(s.use)[1]
    if s.equations < 10 + len(fnames):
        raise DataError(f"{where}: {s.equations} torque equations are left after the exclusions and the filter's "
                        f"transients, for {10 + len(fnames)} parameters; log longer runs")
    names = reg.names + fnames
    W = np.concatenate([Yp, F], axis=2)
    mark = time.perf_counter()
    excited = excitation(Yp[use]) >= UNEXCITED
    if excited:
        ls = least_squares(W[use], y[use], joint, n, names, f"{where}: the logged motion")
        pi, cov_all = ls.pi[:10], ls.covariance
        cov = cov_all[:10, :10]
        fit = W @ ls.pi
    else:        # the inertia not excited: m, h with I_o of a point mass plus the shape, to a fixed point
        cols = [0, 1, 2, 3] + list(range(10, 10 + len(fnames)))
        pi = np.zeros(10)
        for _ in range(FIXED_POINT):
            io = _point_mass_io(pi[0], pi[1:4], shape * max(pi[0], 0.0))
            ls = least_squares(W[use][:, cols], (y - Yp[:, :, 4:] @ io)[use], joint, n,
                               tuple(names[k] for k in cols), f"{where}: the logged motion (mass and centre of mass)")
            step = np.abs(ls.pi[:4] - pi[:4]).max()
            pi = np.concatenate([ls.pi[:4], _point_mass_io(ls.pi[0], ls.pi[1:4], shape * max(ls.pi[0], 0.0))])
            if step <= 1e-12 * max(1.0, np.abs(pi[:4]).max()):
                break
        cov_all = ls.covariance
        cov = np.zeros((10, 10))
        cov[:4, :4] = cov_all[:4, :4]
        fit = Yp @ pi + W[:, :, 10:] @ ls.pi[4:]
    seconds["estimate"] = time.perf_counter() - mark
    k0 = len(ls.pi) - len(fnames)
    return PayloadFit(pi=pi, cov=cov, inertia_excited=excited, ls=ls, names=names, friction_names=fnames,
                      friction=ls.pi[k0:], friction_std=ls.std[k0:],
                      refused={j: r for j, r in refused.items() if not force}, samples=s,
                      rms_file=_rms(y, use), rms_fit=_rms(y - fit, use), cond=ls.cond, seconds=seconds)
