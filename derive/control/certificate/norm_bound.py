"""The observer certificate's decision for many joints: one matrix bound, no branch and bound.

Past MAX_VERTEX_DEPS coordinates with J's series past its budget (derive.control.certificate.inertia: the
bounds come from J's supremum and degrees), branch and bound over m angles and the speed box's 2^m
vertices cost exponentially in m. Here (*) of derive.control.certificate is decided for every theta
and every speed at once, in J's diagonal scale D^-1 N D^-1 (sc below):

    N = W + W^T - sum_k theta'_k dJ/dq_k - 2 beta J  >=  lambda_min(S) - v ||sum_k s_k B_k||_2 - 2 beta ||B_J||_2

with |dJ_ab/dq_k| <= B_k,ab for every theta (Bernstein's inequality on J's supremum, per entry,
derive.control.certificate.interval), |J_ab| <= B_J,ab, and Weyl's inequality (||X||_2 <= rho(B) for a symmetric X
with |X| <= B entrywise). Sound, never exact: failing it refutes nothing (``unproven``; a refutation
comes only from N itself at seeded samples). Cost: m n^2 for the bound, samples x vertices x n^3 for
the search for a refutation, the vertices a seeded sample of at most MAX_SIGNS when 2^m is more.
"""
from __future__ import annotations

import itertools

import numpy as np

MAX_VERTEX_DEPS = 8   # past this many coordinates without J's series: this module's bound
MAX_SIGNS = 256       # speed-box vertices enumerated (a seeded sample of them past this)
ELEMENTS = 1 << 22    # numbers per batch of sampled N (points x vertices x n^2)


def sign_patterns(m: int, seed: int = 0) -> np.ndarray:
    """The box's vertex signs (V x m): all 2^m when at most MAX_SIGNS, else all +1 and a seeded sample
    of MAX_SIGNS - 1 others; each pattern's negative follows in the second half (the rows i and
    V - 1 - i are opposite), as the enumeration has them."""
    if m == 0:
        return np.zeros((1, 0))
    if 2 ** m <= MAX_SIGNS:
        return np.array(list(itertools.product((1.0, -1.0), repeat=m)))
    rng = np.random.default_rng(seed)
    half = np.vstack([np.ones((1, m)), np.where(rng.random((MAX_SIGNS // 2 - 1, m)) < 0.5, -1.0, 1.0)])
    half[:, 0] = 1.0
    return np.vstack([half, -half[::-1]])


def norm_lower_bound(model, W: np.ndarray, shape: np.ndarray, v: float, beta: float) -> float:
    """A lower bound of lambda_min(D^-1 N D^-1) over every theta and every speed |theta'_k| <= v s_k
    (module docstring), minus nothing else: the caller compares it with its float margin."""
    from derive.control.certificate.decision import _spectral_norm

    sc = np.outer(model.scale, model.scale)
    S = (W + W.T) * sc
    s = np.array([shape[c.index] for c in model.deps], dtype=float)
    U = np.einsum("k,kab->ab", np.abs(s), model.first()) * sc
    out = float(np.linalg.eigvalsh(S)[0]) - v * float(_spectral_norm(U))
    if beta:
        out -= 2.0 * beta * float(_spectral_norm(model.supremum * sc))
    return out


def norm_speed_bound(model, W: np.ndarray, shape: np.ndarray, beta: float) -> float:
    """The largest v :func:`norm_lower_bound` proves (positive slack), 0 when none."""
    at0 = norm_lower_bound(model, W, shape, 0.0, beta)
    slope = at0 - norm_lower_bound(model, W, shape, 1.0, beta)
    if at0 <= 0:
        return 0.0
    return float("inf") if slope <= 0 else at0 / slope


def norm_rate_bound(model, W: np.ndarray, shape: np.ndarray, v: float) -> float:
    """The largest beta :func:`norm_lower_bound` proves on the box of scale v, 0 when none."""
    at0 = norm_lower_bound(model, W, shape, v, 0.0)
    slope = at0 - norm_lower_bound(model, W, shape, v, 1.0)
    if at0 <= 0:
        return 0.0
    return float("inf") if slope <= 0 else at0 / slope


def sample_count(vertices: int, n: int, want: int) -> int:
    """Points per batch of sampled N: ``want``, fewer so that points x vertices x n^2 <= ELEMENTS."""
    return int(max(8, min(want, ELEMENTS // max(1, vertices * n * n))))
