"""Numeric J(q) and gravity torque straight from a Chain (NumPy), for chain-level tests.

Independent of derive.dynamics: each body's kinetic energy from its frame's
velocity, T = 1/2 m v.v - v^T [h]x w + 1/2 w^T I_o w (all in the base frame),
so J = sum_k Jv^T m Jv + Jv^T [h]x^T Jw + Jw^T [h]x Jv + Jw^T I_o Jw (plus the
reflected rotor inertias when given), and the gravity torque
G_j = -sum_k g^T (m Jv_kj + Jw_kj x h_k).
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from derive.model.chain import Chain, JointType


def _f(m) -> np.ndarray:
    return np.array(sp.Matrix(m).evalf(30).tolist(), dtype=float)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _rot(axis: np.ndarray, q: float) -> np.ndarray:
    K = _skew(axis)
    return np.eye(3) + np.sin(q) * K + (1 - np.cos(q)) * K @ K


class NumericChain:
    """A chain with its parameter values put in, as floats."""

    def __init__(self, chain: Chain, values: dict | None = None):
        values = dict(chain.values()) if values is None else values
        self.n = chain.n
        self.types = [j.type for j in chain.joints]
        self.R0 = [_f(j.origin.R.xreplace(values)) for j in chain.joints]
        self.p0 = [_f(j.origin.p.xreplace(values)).ravel() for j in chain.joints]
        self.axis = [_f(j.axis).ravel() for j in chain.joints]
        self.m = [float(sp.sympify(b.mass).xreplace(values)) for b in chain.bodies]
        self.h = [_f(b.first_moment.xreplace(values)).ravel() for b in chain.bodies]
        self.I = [_f(b.inertia.xreplace(values)) for b in chain.bodies]
        self.g = _f(chain.gravity.xreplace(values)).ravel()

    def poses(self, q: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        R, p, out = np.eye(3), np.zeros(3), []
        for i in range(self.n):
            p = p + R @ self.p0[i]
            R = R @ self.R0[i]
            if self.types[i] is JointType.PRISMATIC:
                p = p + R @ self.axis[i] * q[i]
            else:
                R = R @ _rot(self.axis[i], q[i])
            out.append((R.copy(), p.copy()))
        return out

    def jacobians(self, q: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        poses = self.poses(q)
        out = []
        for k, (_, pk) in enumerate(poses):
            Jv, Jw = np.zeros((3, self.n)), np.zeros((3, self.n))
            for j in range(k + 1):
                Rj, pj = poses[j]
                a = Rj @ self.axis[j]
                if self.types[j] is JointType.PRISMATIC:
                    Jv[:, j] = a
                else:
                    Jw[:, j] = a
                    Jv[:, j] = np.cross(a, pk - pj)
            out.append((Jv, Jw))
        return out

    def inertia_matrix(self, q: np.ndarray) -> np.ndarray:
        J = np.zeros((self.n, self.n))
        for (Rk, _), (Jv, Jw), m, h, I in zip(self.poses(q), self.jacobians(q), self.m, self.h, self.I):
            hw, Iw = Rk @ h, Rk @ I @ Rk.T
            S = _skew(hw)
            J += m * Jv.T @ Jv + Jv.T @ S.T @ Jw + Jw.T @ S @ Jv + Jw.T @ Iw @ Jw
        return J

    def gravity_torque(self, q: np.ndarray) -> np.ndarray:
        G = np.zeros(self.n)
        for (Rk, _), (Jv, Jw), m, h in zip(self.poses(q), self.jacobians(q), self.m, self.h):
            hw = Rk @ h
            G -= m * Jv.T @ self.g + np.cross(Jw.T, hw) @ self.g
        return G
