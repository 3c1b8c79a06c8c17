"""The Coriolis matrix C(q, q') of the Christoffel symbols of J(q).

C_kj = sum_i 1/2 (dJ_kj/dq_i + dJ_ki/dq_j - dJ_ij/dq_k) q'_i  (Christoffel
symbols of the first kind). Written with the generalized momentum p = J q'
and its Jacobian A = dp/dq (A_kj = sum_i dJ_ki/dq_j q'_i), the three sums are
J', A and A^T:

    C = 1/2 (J' + A - A^T),   J' = sum_i dJ/dq_i q'_i,

so C needs the n derivatives dJ/dq_i once, not n^3 Christoffel symbols. Then
J' - 2C = A^T - A is skew-symmetric and C q' = J' q' - 1/2 A^T q' is the
velocity part of the bias (A q' = J' q').
"""
from __future__ import annotations

from collections.abc import Sequence

import sympy as sp


def coriolis_matrix(J: sp.Matrix, q: Sequence[sp.Symbol], dq: Sequence[sp.Symbol]) -> sp.Matrix:
    """C (n x n) of J (n x n, symmetric) in the coordinates q and rates dq."""
    n = J.rows
    # dJ[i] = dJ/dq_i, the upper triangle differentiated and mirrored
    dJ = []
    for qi in q:
        D = sp.zeros(n, n)
        for r in range(n):
            for c in range(r, n):
                D[r, c] = D[c, r] = sp.diff(J[r, c], qi)
        dJ.append(D)
    Jdot = sp.zeros(n, n)
    A = sp.zeros(n, n)
    for k in range(n):
        for j in range(n):
            Jdot[k, j] = sp.Add(*[dJ[i][k, j] * dq[i] for i in range(n)])
            A[k, j] = sp.Add(*[dJ[j][k, i] * dq[i] for i in range(n)])
    return (Jdot + A - A.T) / 2
