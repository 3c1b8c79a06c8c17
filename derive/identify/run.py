"""derive identify as one function: an arm and a log -> the identified parameters.

arm -> regressor (derive.identify.regressor) -> the log's samples (derive.identify.log,
derive.identify.signals) -> weighted least squares and the physically consistent
estimate (derive.identify.estimate). The arm file and the report are written by the CLI
from the :class:`Identification` (derive.identify.armfile, derive.identify.report).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
from threadpoolctl import threadpool_limits

from derive.errors import DataError, DerivationError
from derive.identify.estimate import Consistent, LeastSquares, Model, consistent, least_squares, planar_model, \
    spatial_model
from derive.identify.log import Log, minimum_samples
from derive.identify.regressor import Regressor, derive_regressor
from derive.identify import CUTOFF
from derive.identify.signals import Samples, drive_constants, prepare
from derive.model.spec import Arm


@dataclass(frozen=True)
class Identification:
    """What derive identify found: the regressor, the samples, the base-parameter names and
    units (with fc1..n under ``coulomb``), the arm file's base parameters, the estimates,
    the standard parameters (prior and consistent), the torque each estimate predicts at
    the samples (N x n), the drives' back-EMF damping, timings [s]."""

    arm: Arm
    reg: Regressor
    samples: Samples
    coulomb: bool
    names: tuple[str, ...]
    units: tuple[str, ...]
    prior_pi: np.ndarray
    ls: LeastSquares
    cons: Consistent
    phi0: np.ndarray
    model: Model
    predicted_ls: np.ndarray
    predicted_cons: np.ndarray
    emf: np.ndarray
    seconds: dict = field(default_factory=dict)

    def rms(self, predicted: np.ndarray) -> np.ndarray:
        """Residual RMS per joint of a prediction [N m]."""
        return np.sqrt(np.mean((self.samples.y - predicted) ** 2, axis=0))


def reach(arm: Arm) -> float:
    """A length scale of the arm [m]: the sum of its joints' offsets (at least 0.1 m)."""
    values = arm.chain.values()
    total = sum(float(sp.sqrt(sum(x ** 2 for x in j.origin.p.xreplace(values)))) for j in arm.chain.joints)
    return max(total, 0.1)


def _model(arm: Arm, phi0: np.ndarray, emf: np.ndarray, coulomb: bool) -> Model:
    n = arm.n
    if arm.spatial is not None:
        return spatial_model(phi0, n, reach(arm), emf, coulomb)
    links, fixed = [], []
    for i, link in enumerate(arm.links):
        m, c = float(link.mass), float(link.length / 2 if link.com_default else link.com)
        ic = float(link.mass * link.length ** 2 / 12) if link.uniform_rod else float(link.inertia)
        links.append((m, m * c, ic + m * c * c))
        f = np.zeros(10)
        for pm in arm.point_masses:
            if pm.link == i:
                mp, rp = float(pm.mass), float(pm.distance)
                f[0] += mp
                f[1] += mp * rp
                f[7] += float(pm.inertia) + mp * rp * rp
                f[9] += float(pm.inertia) + mp * rp * rp
        fixed.append(f)
    model = planar_model(phi0, links, fixed, reach(arm), emf, coulomb)
    if not np.allclose(model.F @ model.z0 + model.g, phi0, rtol=1e-12, atol=1e-15):
        raise DerivationError("identify: the planar links and point masses do not add up to the chain's bodies")
    return model


def regression(reg: Regressor, s: Samples, coulomb: bool) -> tuple[np.ndarray, np.ndarray]:
    """(W, y): the regressor stacked sample by sample (N n x p, plus n Coulomb columns
    sign(theta'_j), filtered as the torque, on joint j's rows under ``coulomb``) and the torques (N n)."""
    W = reg.evaluate(s.theta, s.dtheta, s.ddtheta)                 # N x n x p
    if coulomb:
        N, n = s.theta.shape
        C = np.zeros((N, n, n))
        C[:, np.arange(n), np.arange(n)] = s.sign
        W = np.concatenate([W, C], axis=2)
    return W.reshape(-1, W.shape[2]), s.y.reshape(-1)


def identify(arm: Arm, log: Log, cutoff: float = CUTOFF, coulomb: bool = False,
             reg: Regressor | None = None) -> Identification:
    """Identify ``arm``'s base and standard parameters from ``log`` (module docstring).
    DataError for a log that cannot give them (too short, a current log without motor
    constants, a motion that leaves base parameters unexcited: named)."""
    with threadpool_limits(1, "blas"):      # many small LAPACK calls (pyproject.toml)
        return _identify(arm, log, cutoff, coulomb, reg)


def _identify(arm: Arm, log: Log, cutoff: float, coulomb: bool, reg: Regressor | None) -> Identification:
    seconds = {}
    started = time.perf_counter()
    reg = derive_regressor(arm.chain) if reg is None else reg
    n = reg.n
    seconds["regressor"] = time.perf_counter() - started
    friction = tuple(f"fc{j}" for j in range(1, n + 1)) if coulomb else ()
    names = reg.names + friction
    units = tuple(b.unit for b in reg.base) + tuple("N m" if j.type.rotates else "N"
                                                    for j, _ in zip(arm.chain.joints, friction))
    minimum_samples(log, len(names), n)
    mark = time.perf_counter()
    s = prepare(log, arm.chain, cutoff)
    seconds["filter"] = time.perf_counter() - mark
    if len(s.t) * n < len(names):
        raise DataError(f"{log.source}: {len(s.t)} rows are left after dropping the filter's transients and "
                        f"decimating by {s.decimation} (to 2 x the cut-off {cutoff:g} Hz): {len(s.t) * n} equations "
                        f"for {len(names)} parameters; log a longer run (or raise --cutoff)")
    mark = time.perf_counter()
    W, y = regression(reg, s, coulomb)
    seconds["regressor_rows"] = time.perf_counter() - mark
    mark = time.perf_counter()
    ls = least_squares(W, y, n, names, f"{log.source}: the logged motion")
    seconds["least_squares"] = time.perf_counter() - mark
    _, emf, _ = drive_constants(arm.chain)
    phi0 = np.array([float(v) for v in reg.prior] + [0.0] * (n if coulomb else 0))
    K = reg.K if not coulomb else np.block([[reg.K, np.zeros((reg.p, n))],
                                            [np.zeros((n, reg.K.shape[1])), np.eye(n)]])
    model = _model(arm, phi0, emf, coulomb)
    mark = time.perf_counter()
    cons = consistent(ls, K, model)
    seconds["consistent"] = time.perf_counter() - mark
    prior_pi = K @ phi0
    N = len(s.t)
    return Identification(arm=arm, reg=reg, samples=s, coulomb=coulomb, names=names, units=units, prior_pi=prior_pi,
                          ls=ls, cons=cons, phi0=phi0, model=model, predicted_ls=(W @ ls.pi).reshape(N, n),
                          predicted_cons=(W @ cons.pi).reshape(N, n), emf=emf, seconds=seconds)
