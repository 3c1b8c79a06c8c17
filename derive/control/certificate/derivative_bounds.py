"""Bounds of J's derivatives from its Fourier coefficients (derive.control.certificate.inertia): the factors
each derivative order multiplies a harmonic by, summed over the coefficients' magnitudes."""
from __future__ import annotations

import itertools

import numpy as np

ROUNDING = 1e-12   # relative rounding of the discrete Fourier transform's coefficients


def fourier_derivative_bounds(coef: np.ndarray, F: np.ndarray, polynomial=None, half=None,
                               fourth: bool = False) -> tuple[np.ndarray, ...]:
    """Bounds of |d^2 J/dq_j dq_k| and |d^3 J/dq_i dq_j dq_k| (m x m x n x n, m x m x m x n x n;
    with ``fourth`` also |d^4 J|, m x m x m x m x n x n) valid for every q, from J's coefficients
    C_f (coef: K x n x n) of the terms exp(i f.q) at integer frequencies f (F: K x m):
    sum_f |C_f| |f_j f_k|, sum_f |C_f| |f_i f_j f_k|, ..., each |C_f| inflated by ROUNDING times the
    sum of all of them (the transform's rounding).

    ``polynomial[k]`` (m booleans): coordinate k is a length (a prismatic joint), and its column
    of F holds the power e of t^e, t = (q_k - mid_k) / half[k] in [-1, 1] over its span: the o-th
    derivative of t^e is at most e! / (e - o)! / half[k]^o there (0 for o > e) and |t| <= 1.
    One matrix product over the K terms for every index tuple at once."""
    m, n = F.shape[1], coef.shape[1]
    orders = (2, 3, 4) if fourth else (2, 3)
    out = tuple(np.zeros((m,) * o + (n, n)) for o in orders)
    if m == 0:
        return out
    mag = np.abs(coef).reshape(coef.shape[0], n * n)
    mag = mag + (ROUNDING * mag.sum(axis=0, keepdims=True) + 1e-300)
    absF = np.abs(F).astype(float)
    poly = [False] * m if polynomial is None else list(polynomial)

    def factor(k: int, order: int) -> np.ndarray:
        """The bound of the order-th derivative in coordinate k, per term (K)."""
        if not poly[k]:
            return absF[:, k] ** order
        e = absF[:, k]
        falling = np.ones_like(e)
        for r in range(order):
            falling = falling * np.maximum(e - r, 0.0)
        return falling / float(half[k]) ** order

    def weight(axes: tuple[int, ...]) -> np.ndarray:
        w = np.ones(F.shape[0])
        for k in set(axes):
            w = w * factor(k, axes.count(k))
        return w

    tuples = [t for o in orders for t in itertools.combinations_with_replacement(range(m), o)]
    sums = (np.array([weight(t) for t in tuples]) @ mag).reshape(-1, n, n)
    for t, value in zip(tuples, sums):
        target = out[orders.index(len(t))]
        for perm in set(itertools.permutations(t)):
            target[perm] = value
    return out
