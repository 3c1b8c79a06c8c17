"""The plant's zero-order hold over a sample for derive.control.sampling: (Phi, Gamma) of the
linearisation x' = A x + Bu u at every operating point, the matrix exponential of [A Bu; 0 0] dt, and the
store in which the forms' searches share them."""
from __future__ import annotations

import math

import numpy as np

_TAYLOR_DEGREE, _PS_STEP = 18, 4   # expm's Taylor polynomial and its Paterson-Stockmeyer step
CHUNK_ELEMENTS = 1 << 21             # numbers of one chunk of the stack expm exponentiates at once


def expm(M: np.ndarray) -> np.ndarray:
    """exp of a stack of square matrices (... x k x k): scaling and squaring of a degree-18 Taylor
    polynomial (relative error below 1e-15 at norms <= 1/2 after scaling), the polynomial evaluated
    by Paterson and Stockmeyer's scheme (Higham, Functions of Matrices, 2008, sec. 4.4.3: A^2, A^3,
    A^4, then Horner's rule in A^4 over coefficients that are combinations of I, A, A^2, A^3): 7
    matrix products instead of 18.

    The stack is exponentiated in chunks of at most CHUNK_ELEMENTS numbers, each at the scaling of
    the whole stack (its largest norm), so every matrix's bits are those of one pass over the stack
    while the powers held at once stay small (a 20-joint chain's 3n x 3n transitions at thousands of
    operating points: gigabytes of powers in one pass)."""
    norm = np.abs(M).sum(axis=-1).max(axis=-1).max() if M.size else 0.0
    s = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    k = M.shape[-1]
    step = max(1, CHUNK_ELEMENTS // max(1, k * k))
    if M.ndim <= 2 or M.shape[0] <= step:
        return _expm_scaled(M, s)
    out = np.empty_like(M, dtype=float)
    for i in range(0, M.shape[0], step):
        out[i:i + step] = _expm_scaled(M[i:i + step], s)
    return out


def _expm_scaled(M: np.ndarray, s: int) -> np.ndarray:
    """:func:`expm` of a stack at the scaling 2^-s."""
    A = M / (2.0 ** s)
    powers = [None, A]
    for _ in range(2, _PS_STEP):
        powers.append(powers[-1] @ A)
    top = powers[-1] @ A                                       # A^4
    coeff = [1.0 / math.factorial(k) for k in range(_TAYLOR_DEGREE + 1)]
    diagonal = np.arange(M.shape[-1])
    scratch = np.empty_like(A)

    def block(j: int) -> np.ndarray:   # sum_i coeff[4 j + i] A^i, in place; A^0 = I: the diagonal only
        out = np.zeros_like(A)
        for i in range(1, _PS_STEP):
            if _PS_STEP * j + i <= _TAYLOR_DEGREE:
                out += np.multiply(powers[i], coeff[_PS_STEP * j + i], out=scratch)
        out[..., diagonal, diagonal] += coeff[_PS_STEP * j]
        return out

    E = block(_TAYLOR_DEGREE // _PS_STEP)
    for j in range(_TAYLOR_DEGREE // _PS_STEP - 1, -1, -1):
        E = E @ top
        E += block(j)
    for _ in range(s):
        E = E @ E
    return E


def zoh(L: dict, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The plant's zero-order hold over dt at every operating point: (Phi, Gamma) = the blocks of
    exp([A Bu; 0 0] dt) (P x 2n x 2n, P x 2n x n; its scaling is the stack's: the same stack, the same
    bits)."""
    m, n = L["A"].shape[-1], L["Bu"].shape[-1]
    aug = np.zeros((L["A"].shape[0], m + n, m + n))
    aug[:, :m, :m], aug[:, :m, m:] = L["A"], L["Bu"]
    E = expm(aug * dt)
    return E[:, :m, :m], E[:, :m, m:]


HOLDS_BYTES = 1 << 22   # the holds the forms' searches keep for each other (derive.control.sampling.limits): my3
                        # shares 23 of its 134; a 7-joint arm's forms rarely share A to the bit (~30 MB for 1)


def bound(holds: dict) -> None:
    """Drop the oldest of ``holds`` ((dt, A bytes, Bu bytes) -> (Phi, Gamma), views of one exp, in the
    order they came) while their keys and exps take more than HOLDS_BYTES."""
    def size(key: tuple, hold: tuple[np.ndarray, np.ndarray]) -> int:
        Phi, Gamma = hold
        k = Phi.shape[-1] + Gamma.shape[-1]
        return len(key[2]) + len(key[3]) + Phi.shape[0] * k * k * Phi.itemsize

    total = sum(size(k, v) for k, v in holds.items())
    for key in list(holds):
        if total <= HOLDS_BYTES:
            break
        total -= size(key, holds.pop(key))
