"""The prior of derive identify: the arm file's standard parameters and how well they are known.

The physically consistent estimate (derive.identify.consistent) is a maximum a posteriori
estimate: the data's weighted residual plus a Gaussian prior centred on the arm file's
values z0 with a standard deviation S_k per parameter, which the user states through one
number, the relative prior uncertainty R (``derive identify --prior-uncertainty``, default
PRIOR_UNCERTAINTY). Per body i, with m_s its mass (at least 1 % of the arm's mean body
mass, MASS_FLOOR) and l its size (the root-mean-square distance of its mass from its
joint frame's origin, sqrt(tr(I)/(2 m)), or |c|, whichever is larger; at least
LENGTH_FLOOR of the arm's reach):

* mass m: R m_s; each first moment h = m c: R m_s l; each inertia entry: R m_s l^2;
* per joint, the reflected rotor inertia Ia: R |Ia_0|, at least the arm's inertia scale
  M r^2 / 10 (M: the arm's mass, r: its reach), viscous friction fv: R |fv_0|, at least
  the torque scale g M r per rad/s (per m/s on a prismatic joint), Coulomb friction fc:
  R |fc_0|, at least g M r / 10: a file that gives 0 (what ``derive init`` writes) leaves
  them to the data.

The weight of the prior is thus set by what the user knows of the file, not by the data:
the directions the data does not see stay at the file's values (the estimate's
component there is 0), what it sees follows the data as soon as it carries more
information than the prior. A parameter with S_k = 0 is held at its prior (the decision
variables of the estimate are the others), which is how a subset of the parameters
(a payload's, say) is identified with the rest known.

A planar ``[[link]]`` arm's bodies keep its model: each link a lamina along its x axis
(z = mass, first moment m c on the axis, inertia Izz about the joint) with its point
masses fixed, so its LMI is that of the lamina, [[Izz, hx], [hx, m]] >= 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from derive.identify.parameters import pseudo_inertia

PRIOR_UNCERTAINTY = 0.5    # default R: the file's masses and inertias right to 50 % (one standard deviation)
MASS_FLOOR = 1e-2          # of the mean body mass: a massless body in the file is still allowed mass
LENGTH_FLOOR = 0.05        # of the arm's reach: a body's size at least this
MARGIN = 1e-7              # each LMI, scaled to its body's size, holds with this margin (exact checks pass)


@dataclass(frozen=True)
class Model:
    """The standard parameters as an affine function phi = F z + g of the decision variables
    z: prior z0, prior standard deviations S (0: held at z0), names of z; lmis: per body
    (indices of z, a function from those entries to the matrix that must be positive
    semidefinite, the diagonal D of a congruence D P D that scales it to O(1)); lower:
    (index, bound) of z; body: per z the body it belongs to (0 for drive parameters)."""

    F: np.ndarray
    g: np.ndarray
    z0: np.ndarray
    S: np.ndarray
    names: tuple[str, ...]
    lmis: tuple
    lower: tuple[tuple[int, float], ...]
    body: tuple[int, ...]

    def held(self, free: np.ndarray) -> "Model":
        """The same model with every z not in ``free`` (bool, len z) held at its prior (S = 0)."""
        return Model(F=self.F, g=self.g, z0=self.z0, S=np.where(free, self.S, 0.0), names=self.names, lmis=self.lmis,
                     lower=self.lower, body=self.body)


def _size(m: float, trace: float, c: float, floor: float) -> float:
    """A body's size [m]: the rms distance of its mass from the frame origin, or |c|."""
    return max(math.sqrt(max(trace, 0.0) / (2 * m)) if m > 0 else 0.0, abs(c), floor)


def _drives(prior: np.ndarray, n: int, emf: np.ndarray, coulomb: bool, uncertainty: float, arm_mass: float,
            reach: float, prismatic: tuple[bool, ...]) -> tuple[np.ndarray, list[tuple[int, float]], list[str]]:
    """(S, bounds (index, lower bound), names) of the drive parameters Ia (>= 0), fv (>= the
    back-EMF: the joint's viscous friction >= 0) and fc (>= 0), indices from 0."""
    S, lower = np.zeros(len(prior)), []
    torque = 9.81 * arm_mass * reach
    for j in range(n):
        S[j] = max(uncertainty * abs(prior[j]), arm_mass * reach ** 2 / 10)
        S[n + j] = max(uncertainty * abs(prior[n + j]), torque / (reach if prismatic[j] else 1.0))
        lower += [(j, 0.0), (n + j, float(emf[j]))]
        if coulomb:
            S[2 * n + j] = max(uncertainty * abs(prior[2 * n + j]), torque / 10)
            lower.append((2 * n + j, 0.0))
    names = [f"Ia{j}" for j in range(1, n + 1)] + [f"fv{j}" for j in range(1, n + 1)]
    names += [f"fc{j}" for j in range(1, n + 1)] if coulomb else []
    return S, lower, names


def spatial_model(prior: np.ndarray, names: tuple[str, ...], n: int, reach: float, emf: np.ndarray, coulomb: bool,
                  uncertainty: float = PRIOR_UNCERTAINTY, prismatic: tuple[bool, ...] | None = None) -> Model:
    """Every body's ten parameters free (URDF and DH arms): z = phi; ``names``: of phi."""
    size = len(prior)
    lmis, S = [], np.zeros(size)
    total = max(float(sum(prior[10 * i] for i in range(n))), 1e-3)
    for i in range(n):
        b = prior[10 * i: 10 * i + 10]
        ms = max(b[0], MASS_FLOOR * total / n, 1e-6)
        lb = _size(b[0], b[4] + b[7] + b[9], float(np.linalg.norm(b[1:4])) / ms, LENGTH_FLOOR * reach)
        S[10 * i: 10 * i + 10] = uncertainty * np.array([ms] + [ms * lb] * 3 + [ms * lb ** 2] * 6)
        D = np.array([1 / lb] * 3 + [1.0]) / math.sqrt(ms)
        lmis.append((tuple(range(10 * i, 10 * i + 10)), pseudo_inertia, D))
    S[10 * n:], lower, _ = _drives(prior[10 * n:], n, emf, coulomb, uncertainty, total, reach,
                                   prismatic or (False,) * n)
    body = tuple(1 + k // 10 if k < 10 * n else 0 for k in range(size))
    return Model(F=np.eye(size), g=np.zeros(size), z0=prior.copy(), S=S, names=tuple(names), lmis=tuple(lmis),
                 lower=tuple((10 * n + k, b) for k, b in lower), body=body)


def _lamina(z) -> list[list]:
    """The LMI of a lamina along x with z = (m, hx, Izz) about its joint: [[Izz, hx], [hx, m]]."""
    m, hx, izz = z
    return [[izz, hx], [hx, m]]


def planar_model(prior: np.ndarray, links: list[tuple[float, float, float]], fixed: list[np.ndarray],
                 reach: float, emf: np.ndarray, coulomb: bool, uncertainty: float = PRIOR_UNCERTAINTY) -> Model:
    """A planar arm's model: per link z = (m, hx, Izz) of the link alone (a lamina along x,
    about its joint), the point masses it carries fixed (``fixed``: their ten parameters)."""
    n = len(links)
    drives = len(prior) - 10 * n
    size = 3 * n + drives
    F = np.zeros((len(prior), size))
    g = np.zeros(len(prior))
    z0, S = np.zeros(size), np.zeros(size)
    lmis, names = [], []
    total = max(sum(m for m, _, _ in links) + sum(f[0] for f in fixed), 1e-3)
    for i, ((m, hx, izz), f) in enumerate(zip(links, fixed)):
        F[10 * i, 3 * i] = 1.0                        # m
        F[10 * i + 1, 3 * i + 1] = 1.0                # hx
        F[10 * i + 7, 3 * i + 2] = 1.0                # Iyy = Izz for a lamina along x
        F[10 * i + 9, 3 * i + 2] = 1.0                # Izz
        g[10 * i: 10 * i + 10] = f
        z0[3 * i: 3 * i + 3] = (m, hx, izz)
        ms = max(m, MASS_FLOOR * total / n, 1e-6)
        lb = _size(m, 2 * izz, hx / ms, LENGTH_FLOOR * reach)
        S[3 * i: 3 * i + 3] = uncertainty * np.array([ms, ms * lb, ms * lb ** 2])
        lmis.append(((3 * i, 3 * i + 1, 3 * i + 2), _lamina, np.array([1 / lb, 1.0]) / math.sqrt(ms)))
        names += [f"m{i + 1}", f"hx{i + 1}", f"Izz{i + 1}"]
    F[10 * n:, 3 * n:] = np.eye(drives)
    z0[3 * n:] = prior[10 * n:]
    S[3 * n:], lower, drive_names = _drives(prior[10 * n:], n, emf, coulomb, uncertainty, total, reach, (False,) * n)
    body = tuple(1 + k // 3 if k < 3 * n else 0 for k in range(size))
    return Model(F=F, g=g, z0=z0, S=S, names=tuple(names + drive_names), lmis=tuple(lmis),
                 lower=tuple((3 * n + k, b) for k, b in lower), body=body)
