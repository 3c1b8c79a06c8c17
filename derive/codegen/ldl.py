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


def _product(a: sp.Expr, b: sp.Expr) -> sp.Expr:
    """a b as written (SymPy would merge the factors of a and b, losing the shared ones)."""
    return sp.Mul(a, b, evaluate=False)


@keep_sums
def ldl_factor(A: sp.Matrix) -> tuple[sp.Expr, ...]:
    """The factor of the symmetric positive definite A (n x n, its lower triangle read), negated:
    -L's strictly lower entries row by row, then the n entries of -D^-1. The signs are exact;
    they keep each entry one product: with -1/d_j CasADi keeps LD_ij (-1/d_j) a product, where
    it would write LD_ij (1/d_j) as the quotient LD_ij / d_j (n (n - 1) / 2 divisions more)."""
    n = A.rows
    NL = [[sp.S.Zero] * n for _ in range(n)]   # -L
    LD = [[sp.S.Zero] * n for _ in range(n)]   # L_ik D_k, shared by the rows below
    ninv = [sp.S.Zero] * n                     # -1/D_j

    def rest(i: int, j: int) -> sp.Expr:   # A_ij - sum_k<j L_ik D_k L_jk
        return sp.Add(A[i, j], *(_product(LD[i][k], NL[j][k]) for k in range(j)))

    for j in range(n):
        ninv[j] = -1 / rest(j, j)
        for i in range(j + 1, n):
            LD[i][j] = rest(i, j)
            NL[i][j] = _product(LD[i][j], ninv[j])
    return tuple(NL[i][j] for i, j in _lower(n)) + tuple(ninv)


def factor_symbols(n: int, prefix: str = "ldl") -> tuple[sp.Symbol, ...]:
    """Symbols for a factor (the input port of the kernel that solves with it)."""
    return tuple(sp.Symbol(f"{prefix}{k + 1}", real=True) for k in range(factor_size(n)))


@keep_sums
def ldl_solve(factor, b) -> sp.Matrix:
    """x with L D L^T x = b (n x 1), ``factor`` (-L, -D^-1) as :func:`ldl_factor` gives it:
    L y = b, then L^T x = D^-1 y."""
    n = len(b)
    neg_lower = dict(zip(_lower(n), factor))
    ninv = factor[n * (n - 1) // 2:]
    y = [sp.S.Zero] * n
    for i in range(n):
        y[i] = sp.Add(b[i], *(_product(neg_lower[i, k], y[k]) for k in range(i)))
    x = [sp.S.Zero] * n
    for i in reversed(range(n)):
        x[i] = sp.Add(*(_product(neg_lower[k, i], x[k]) for k in range(i + 1, n))) - _product(y[i], ninv[i])
    return sp.Matrix(x)
