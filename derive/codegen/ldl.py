"""LDL^T factor and solve of a symmetric positive definite matrix, as expressions for kernels.

The generated code solves J x = b for the inertia matrix J (eq. 12, symmetric positive
definite) numerically: A = L D L^T with L unit lower triangular and D diagonal, without
pivoting and without square roots (Golub and Van Loan, *Matrix Computations*, 4th ed.,
sec. 4.1.2; backward stable for a positive definite A, Higham, *Accuracy and Stability of
Numerical Algorithms*, 2nd ed., sec. 10.1). n^3/6 multiplications for the factor, n^2 for a
solve, n divisions. The factor is an output of one kernel and the input of another
(:func:`factor_symbols`): the law's kernel factors J once, the observer's step solves with it.

Entries are SymPy expressions over the entries of A (shared, never expanded); the printed
order of operations is CasADi's (derive.codegen.casadi_bridge).
"""
from __future__ import annotations

import sympy as sp

from derive.dynamics.spatial import keep_sums


def factor_size(n: int) -> int:
    """The number of reals of a factor of an n x n matrix: n (n - 1) / 2 of L, n of D^-1."""
    return n * (n - 1) // 2 + n


def _lower(n: int) -> list[tuple[int, int]]:
    """(i, j), i > j, of L's strictly lower entries, row by row."""
    return [(i, j) for i in range(n) for j in range(i)]


@keep_sums
def ldl_factor(A: sp.Matrix) -> tuple[sp.Expr, ...]:
    """The factor of the symmetric positive definite A (n x n, its lower triangle read):
    L's strictly lower entries row by row, then the n entries of D^-1."""
    n = A.rows
    L = [[sp.S.Zero] * n for _ in range(n)]
    LD = [[sp.S.Zero] * n for _ in range(n)]   # L_ik D_k, shared by the rows below
    dinv = [sp.S.Zero] * n

    def dot(i: int, j: int) -> sp.Expr:   # sum_k<j LD_ik L_jk, products kept as written
        return sp.Add(*(sp.Mul(LD[i][k], L[j][k], evaluate=False) for k in range(j)))

    for j in range(n):
        dinv[j] = 1 / (A[j, j] - dot(j, j))
        for i in range(j + 1, n):
            LD[i][j] = A[i, j] - dot(i, j)
            # one rounding: LD / d (CasADi writes a product with 1 / d as that quotient)
            L[i][j] = sp.Mul(LD[i][j], dinv[j], evaluate=False)
    return tuple(L[i][j] for i, j in _lower(n)) + tuple(dinv)


def factor_symbols(n: int, prefix: str = "ldl") -> tuple[sp.Symbol, ...]:
    """Symbols for a factor (the input port of the kernel that solves with it)."""
    return tuple(sp.Symbol(f"{prefix}{k + 1}", real=True) for k in range(factor_size(n)))


@keep_sums
def ldl_solve(factor, b) -> sp.Matrix:
    """x with L D L^T x = b (n x 1), ``factor`` as :func:`ldl_factor` gives it."""
    n = len(b)
    lower = dict(zip(_lower(n), factor))
    dinv = factor[n * (n - 1) // 2:]
    y = [sp.S.Zero] * n
    for i in range(n):
        y[i] = b[i] - sum((lower[i, k] * y[k] for k in range(i)), sp.S.Zero)
    x = [sp.S.Zero] * n
    for i in reversed(range(n)):
        x[i] = y[i] * dinv[i] - sum((lower[k, i] * x[k] for k in range(i + 1, n)), sp.S.Zero)
    return sp.Matrix(x)
