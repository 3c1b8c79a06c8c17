"""derive identify as one function: an arm and its logs -> the identified parameters.

arm -> regressor (derive.identify.regressor) -> each log's kept samples (derive.identify.log,
derive.identify.exclude), filtered and differentiated on its own (derive.identify.signals)
-> the regression of every log stacked -> weighted least squares (derive.identify.estimate)
and the physically consistent estimate with the arm file as its prior
(derive.identify.prior, derive.identify.consistent). The arm file and the report are written
by the CLI from the :class:`Identification` (derive.identify.armfile, derive.identify.report),
after the checks of derive.identify.quality.

With ``coulomb``, a joint that moves one way only in the logs gets no Coulomb friction
(its fc sign(theta') would be a constant torque the data cannot tell from gravity or an
offset: the least-squares value is meaningless, the consistent one would sit on its bound
for no reason) unless ``force``; :attr:`Identification.friction_refused` says which and why.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
from threadpoolctl import threadpool_limits

from derive.errors import DataError, DerivationError
from derive.identify import CUTOFF
from derive.identify.consistent import Consistent, consistent, posterior_share
from derive.identify.estimate import LeastSquares, least_squares
from derive.identify.exclude import Exclusion, mask
from derive.identify.log import Log, minimum_samples
from derive.identify.prior import PRIOR_UNCERTAINTY, Model, planar_model, spatial_model
from derive.identify.regressor import Regressor, derive_regressor
from derive.identify.signals import Samples, drive_constants, prepare
from derive.model.chain import JointType
from derive.model.spec import Arm

ONE_SIGNED = 0.05     # a joint whose moving rows have one sign of theta' but for this share moves one way
MOVING = 0.05         # ... moving: |theta'| above this share of the joint's largest speed in the logs


@dataclass(frozen=True)
class Identification:
    """What derive identify found: the regressor, the samples (every log), the base-parameter
    names and units (with fc_j under ``coulomb`` for each joint it is identified on), the
    arm file's base parameters, the estimates, the standard parameters (prior and
    consistent), the prior (``model``, its relative uncertainty) and per decision variable
    the share the data gives (``share``, derive.identify.consistent.posterior_share), the
    torque each estimate predicts at the samples (N x n), the drives' back-EMF damping, the
    exclusion rules, the joints refused a Coulomb friction ({joint (1-based): reason}),
    timings [s]."""

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
    share: np.ndarray
    uncertainty: float
    predicted_ls: np.ndarray
    predicted_cons: np.ndarray
    emf: np.ndarray
    rules: Exclusion = Exclusion()
    friction_refused: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)

    def rms(self, predicted: np.ndarray) -> np.ndarray:
        """Residual RMS per joint of a prediction over the equations used [N m]."""
        use = self.samples.use
        res = np.where(use, self.samples.y - predicted, 0.0)
        return np.sqrt((res ** 2).sum(axis=0) / np.maximum(use.sum(axis=0), 1))

    def explained(self, predicted: np.ndarray) -> np.ndarray:
        """Per joint the share of the torque a prediction explains, 1 - |residual|^2 / |torque|^2
        over the equations used (1: all of it; 0 or less: none)."""
        use = self.samples.use
        torque = (np.where(use, self.samples.y, 0.0) ** 2).sum(axis=0)
        res = (np.where(use, self.samples.y - predicted, 0.0) ** 2).sum(axis=0)
        return 1.0 - res / np.maximum(torque, 1e-300)


def reach(arm: Arm) -> float:
    """A length scale of the arm [m]: the sum of its joints' offsets (at least 0.1 m)."""
    values = arm.chain.values()
    total = sum(float(sp.sqrt(sum(x ** 2 for x in j.origin.p.xreplace(values)))) for j in arm.chain.joints)
    return max(total, 0.1)


def _model(arm: Arm, phi0: np.ndarray, names: tuple[str, ...], emf: np.ndarray, coulomb: bool,
           uncertainty: float) -> Model:
    n = arm.n
    if arm.spatial is not None:
        prismatic = tuple(j.type is JointType.PRISMATIC for j in arm.chain.joints)
        return spatial_model(phi0, names, n, reach(arm), emf, coulomb, uncertainty, prismatic)
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
    model = planar_model(phi0, links, fixed, reach(arm), emf, coulomb, uncertainty)
    if not np.allclose(model.F @ model.z0 + model.g, phi0, rtol=1e-12, atol=1e-15):
        raise DerivationError("identify: the planar links and point masses do not add up to the chain's bodies")
    return model


def _columns(reg: Regressor, s: Samples, friction: tuple[int, ...]) -> np.ndarray:
    """The regressor at every row and joint (N x n x p'), Coulomb columns appended."""
    W = reg.evaluate(s.theta, s.dtheta, s.ddtheta)                 # N x n x p
    if friction:
        N, n = s.theta.shape
        C = np.zeros((N, n, len(friction)))
        for k, j in enumerate(friction):
            C[:, j, k] = s.sign[:, j]
        W = np.concatenate([W, C], axis=2)
    return W


def one_signed(s: Samples, n: int) -> dict[int, str]:
    """{joint (1-based): why} for each joint whose used rows move one way only (module docstring)."""
    out = {}
    for j in range(n):
        v = s.dtheta[s.use[:, j], j]
        top = float(np.abs(v).max()) if v.size else 0.0
        moving = v[np.abs(v) > MOVING * top] if top > 0 else v[:0]
        if moving.size == 0:
            out[j + 1] = "it does not move in the rows used"
            continue
        up = float((moving > 0).mean())
        if min(up, 1 - up) < ONE_SIGNED:
            out[j + 1] = (f"theta'{j + 1} {'> 0' if up > 0.5 else '< 0'} in {100 * max(up, 1 - up):.1f} % of its moving "
                          "rows: one-signed motion, so fc sign(theta') is a constant torque the data cannot tell from "
                          "gravity or an offset")
    return out


def solve(W: np.ndarray, y: np.ndarray, joint: np.ndarray, n: int, names: tuple[str, ...], K: np.ndarray,
          model: Model, what: str) -> tuple[LeastSquares, Consistent, np.ndarray]:
    """Least squares of the base parameters ``names`` (pi = K phi) and the consistent estimate of
    the standard ones phi = F z + g (``model``: the prior; a z with S = 0 is held, so a subset of
    the parameters can be identified with the rest known), and per z the data's share."""
    ls = least_squares(W, y, joint, n, names, what)
    return ls, consistent(ls, K, model), posterior_share(ls, K, model)


def identify(arm: Arm, logs: Log | list[Log], cutoff: float = CUTOFF, coulomb: bool = False,
             reg: Regressor | None = None, rules: Exclusion = Exclusion(), uncertainty: float = PRIOR_UNCERTAINTY,
             force: bool = False) -> Identification:
    """Identify ``arm``'s base and standard parameters from ``logs`` (module docstring), each
    filtered on its own and with the samples ``rules`` keep. DataError for logs that cannot
    give them (too short, a current log without motor constants, a motion that leaves base
    parameters unexcited: named)."""
    with threadpool_limits(1, "blas"):      # many small LAPACK calls (pyproject.toml)
        return _identify(arm, [logs] if isinstance(logs, Log) else list(logs), cutoff, coulomb, reg, rules,
                         uncertainty, force)


def _identify(arm: Arm, logs: list[Log], cutoff: float, coulomb: bool, reg: Regressor | None, rules: Exclusion,
              uncertainty: float, force: bool) -> Identification:
    seconds = {}
    started = time.perf_counter()
    reg = derive_regressor(arm.chain) if reg is None else reg
    n = reg.n
    seconds["regressor"] = time.perf_counter() - started
    families = {log.family for log in logs}
    if len(families) > 1:
        raise DataError(f"{logs[0].source}, ...: expected every log to hold the same signal, got "
                        + " and ".join(f"{f}1..{n}" for f in sorted(families)))
    mark = time.perf_counter()
    parts = []
    if len(logs) == 1:
        minimum_samples(logs[0], reg.p, n)
    for log in logs:
        parts.append(prepare(log, arm.chain, cutoff, mask(log, rules, arm.motors)))
    s = Samples.stack(parts)
    seconds["filter"] = time.perf_counter() - mark
    refused = one_signed(s, n) if coulomb else {}
    friction = tuple(j for j in range(n) if coulomb and (force or j + 1 not in refused))
    names = reg.names + tuple(f"fc{j + 1}" for j in friction)
    units = tuple(b.unit for b in reg.base) + tuple("N m" if arm.chain.joints[j].type.rotates else "N"
                                                    for j in friction)
    where = logs[0].source if len(logs) == 1 else f"{len(logs)} logs ({logs[0].source}, ...)"
    if s.equations < len(names):
        raise DataError(f"{where}: {s.equations} torque equations are left after the exclusions, dropping the "
                        f"filter's transients (2 / f_c = {2 / cutoff:g} s at the ends of every stretch of kept samples) "
                        f"and decimating to 2 x the cut-off {cutoff:g} Hz, for {len(names)} parameters; log longer runs, "
                        "exclude less (or raise --cutoff)")
    mark = time.perf_counter()
    full = _columns(reg, s, friction)
    W, y, joint = full[s.use], s.y[s.use], np.nonzero(s.use)[1]
    seconds["regressor_rows"] = time.perf_counter() - mark
    _, emf, _ = drive_constants(arm.chain)
    phi0 = np.array([float(v) for v in reg.prior] + [0.0] * (n if coulomb else 0))
    standard = tuple(p.name for p in reg.standard) + tuple(f"fc{j}" for j in range(1, n + 1) if coulomb)
    K = reg.K
    if coulomb:
        E = np.zeros((len(friction), n))
        E[np.arange(len(friction)), list(friction)] = 1.0
        K = np.block([[reg.K, np.zeros((reg.p, n))], [np.zeros((len(friction), reg.K.shape[1])), E]])
    model = _model(arm, phi0, standard, emf, coulomb, uncertainty)
    if coulomb:                                     # the refused joints' fc held at 0
        held = np.ones(len(model.z0), bool)
        held[len(model.z0) - n + np.array([j for j in range(n) if j not in friction], int)] = False
        model = model.held(held)
    mark = time.perf_counter()
    ls, cons, share = solve(W, y, joint, n, names, K, model, f"{where}: the logged motion")
    seconds["estimates"] = time.perf_counter() - mark
    return Identification(arm=arm, reg=reg, samples=s, coulomb=coulomb, names=names, units=units, prior_pi=K @ phi0,
                          ls=ls, cons=cons, phi0=phi0, model=model, share=share, uncertainty=uncertainty,
                          predicted_ls=full @ ls.pi, predicted_cons=full @ cons.pi, emf=emf, rules=rules,
                          friction_refused={j: r for j, r in refused.items() if not force}, seconds=seconds)
