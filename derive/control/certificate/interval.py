"""Sound bounds of J(theta) and its derivatives at a cost polynomial in the joints.

J's exact series (derive.control.certificate.inertia: a grid of prod (2 d_k + 1) points) costs 5^m for m
angles: 5^11 rows for a 12-joint chain. Past a budget the certificate's bounds come from here:

1. sup |J_ab| over every theta: interval arithmetic over J's expression graph (each distinct
   subexpression once: cost linear in the graph), an angle's cos and sin in [-1, 1], a prismatic
   coordinate in its travel, every operation rounded outward; and, J being positive semi-definite,
   |J_ab| <= sqrt(sup J_aa sup J_bb).
2. The derivatives from the degrees alone (Bernstein's inequality): a trigonometric polynomial p
   of degree d in an angle has sup |dp/dq| <= d sup |p| over the turn, and a polynomial of degree d
   in t in [-1, 1] has sup |p^(o)| <= T_d^(o)(1) sup |p| (V. A. Markov; T_d the Chebyshev
   polynomial), t = (q - mid) / half. A derivative of J is still such a polynomial in every other
   coordinate, so the factors multiply: sup |d^3 J_ab / dq_i dq_j dq_k| <= f_i f_j f_k S_ab.

Both are sound for every theta (not only within the joint limits); both are looser than the
series (the certificate then needs more cells or ends ``unproven``, which it states). Cost: the
graph once, then m^3 n^2 numbers.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import sympy as sp

from derive.dynamics.program import postorder

_UP = 1.0 + 4.0 * np.finfo(float).eps   # outward rounding of every operation (relative)
_TINY = 1e-300


def _out(lo: float, hi: float) -> tuple[float, float]:
    """[lo, hi] widened by a few units in the last place (each operation's rounding)."""
    return lo - abs(lo) * (_UP - 1) - _TINY, hi + abs(hi) * (_UP - 1) + _TINY


def _mul(a, b):
    p = (a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1])
    return _out(min(p), max(p))


def _pow(a, e: int):
    if e == 0:
        return (1.0, 1.0)
    lo, hi = a
    if e % 2 == 0:
        top = max(abs(lo), abs(hi)) ** e
        bottom = 0.0 if lo <= 0 <= hi else min(abs(lo), abs(hi)) ** e
        return _out(bottom, top)
    return _out(lo ** e, hi ** e)


def _trig(f, a):
    """sin or cos of an interval: its endpoints' values and the extrema inside."""
    lo, hi = a
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo >= 2 * math.pi:
        return (-1.0, 1.0)
    shift = 0.0 if f is math.cos else math.pi / 2      # sin x = cos(x - pi/2)
    x0, x1 = lo - shift, hi - shift
    vals = [math.cos(x0), math.cos(x1)]
    if math.floor(x1 / (2 * math.pi)) > math.floor(x0 / (2 * math.pi)) or x0 <= 0 <= x1:
        vals.append(1.0)
    k = math.floor((x0 - math.pi) / (2 * math.pi))
    if (k + 1) * 2 * math.pi + math.pi <= x1:
        vals.append(-1.0)
    lo_, hi_ = _out(min(vals), max(vals))
    return max(lo_, -1.0), min(hi_, 1.0)


def interval_bounds(exprs, boxes: dict) -> list[tuple[float, float]]:
    """[lower, upper] of each expression for every value of its symbols in ``boxes``
    (symbol -> (lo, hi); a symbol absent is an error), sound under floating-point rounding.
    Operations: +, *, integer powers (a negative one of an interval without 0), sin, cos,
    numbers; any other raises ValueError. Cost: one pass over the distinct subexpressions."""
    memo: dict = {}
    const: dict = {}   # a subexpression without symbols (children first: no tree walk per node)
    for e in postorder([sp.sympify(x) for x in exprs]):
        const[e] = not e.is_Symbol and all(const[a] for a in e.args)
        if e.is_Symbol:
            lo, hi = boxes[e]
            memo[e] = (float(lo), float(hi))
        elif const[e]:
            v = float(e) if e.is_Float else float(sp.N(e, 20))
            memo[e] = _out(v, v)
        elif e.is_Add:
            lo = hi = 0.0
            for a in e.args:
                lo, hi = _out(lo + memo[a][0], hi + memo[a][1])
            memo[e] = (lo, hi)
        elif e.is_Mul:
            acc = (1.0, 1.0)
            for a in e.args:
                acc = _mul(acc, memo[a])
            memo[e] = acc
        elif e.is_Pow and e.exp.is_Integer:
            k = int(e.exp)
            base = memo[e.base]
            if k < 0:
                if base[0] <= 0 <= base[1]:
                    raise ValueError(f"interval bound: 1/x of an interval holding 0 ({base})")
                base = _out(1.0 / base[1], 1.0 / base[0])
                k = -k
            memo[e] = _pow(base, k)
        elif isinstance(e, (sp.sin, sp.cos)):
            memo[e] = _trig(math.sin if isinstance(e, sp.sin) else math.cos, memo[e.args[0]])
        else:
            raise ValueError(f"interval bound: no rule for {type(e).__name__}")
    return [memo[sp.sympify(x)] for x in exprs]


def _add(a, b):
    return _out(a[0] + b[0], a[1] + b[1])


def _neg(a):
    return (-a[1], -a[0])


def interval_gradients(exprs, boxes: dict, coords) -> np.ndarray:
    """Enclosures of d expr / d c for each expression and each symbol c of ``coords`` over the boxes
    (as :func:`interval_bounds`): forward-mode differentiation in interval arithmetic, each node's
    value and gradient once (product rule, k a^(k-1) da, d sin a = cos a da, d cos a = -sin a da).
    Returns len(exprs) x len(coords) x 2 ([lower, upper]). Cost: the graph times len(coords).
    Where Bernstein's factor d sup |J_ab| charges every coordinate with the whole entry, this charges
    a coordinate with the terms that hold it only (a 12-joint chain's J_11 and its wrist angle)."""
    m = len(coords)
    index = {c: k for k, c in enumerate(coords)}
    zero = [(0.0, 0.0)] * m
    memo: dict = {}
    const: dict = {}
    for e in postorder([sp.sympify(x) for x in exprs]):
        const[e] = not e.is_Symbol and all(const[a] for a in e.args)
        if e.is_Symbol:
            lo, hi = boxes[e]
            grad = zero
            if e in index:
                grad = list(zero)
                grad[index[e]] = (1.0, 1.0)
            memo[e] = ((float(lo), float(hi)), grad)
        elif const[e]:
            v = float(e) if e.is_Float else float(sp.N(e, 20))
            memo[e] = (_out(v, v), zero)
        elif e.is_Add:
            val, grad = (0.0, 0.0), list(zero)
            for a in e.args:
                av, ag = memo[a]
                val = _add(val, av)
                if ag is not zero:
                    grad = [_add(g, h) for g, h in zip(grad, ag)]
            memo[e] = (val, grad)
        elif e.is_Mul:
            val, grad = (1.0, 1.0), zero
            for a in e.args:
                av, ag = memo[a]
                if ag is zero and grad is zero:
                    pass
                elif ag is zero:
                    grad = [_mul(g, av) for g in grad]
                elif grad is zero:
                    grad = [_mul(val, h) for h in ag]
                else:
                    grad = [_add(_mul(g, av), _mul(val, h)) for g, h in zip(grad, ag)]
                val = _mul(val, av)
            memo[e] = (val, grad)
        elif e.is_Pow and e.exp.is_Integer:
            k = int(e.exp)
            bv, bg = memo[e.base]
            if k < 0 and bv[0] <= 0 <= bv[1]:
                raise ValueError(f"interval gradient: 1/x of an interval holding 0 ({bv})")
            val = _pow(bv if k > 0 else _out(1.0 / bv[1], 1.0 / bv[0]), abs(k))
            if bg is zero:
                memo[e] = (val, zero)
                continue
            inner = _pow(bv, k - 1) if k > 0 else _pow(_out(1.0 / bv[1], 1.0 / bv[0]), 1 - k)   # a^(k-1)
            factor = _mul((float(k), float(k)), inner)
            memo[e] = (val, [_mul(factor, g) for g in bg])
        elif isinstance(e, (sp.sin, sp.cos)):
            av, ag = memo[e.args[0]]
            s_, c_ = _trig(math.sin, av), _trig(math.cos, av)
            val, slope = (s_, c_) if isinstance(e, sp.sin) else (c_, _neg(s_))
            memo[e] = (val, zero if ag is zero else [_mul(slope, g) for g in ag])
        else:
            raise ValueError(f"interval gradient: no rule for {type(e).__name__}")
    out = np.zeros((len(exprs), m, 2))
    for i, x in enumerate(exprs):
        grad = memo[sp.sympify(x)][1]
        out[i] = np.array(grad, dtype=float).reshape(m, 2)
    return out


def markov_factor(degree: int, order: int) -> float:
    """T_d^(o)(1) = prod_{j<o} (d^2 - j^2) / (2 j + 1): V. A. Markov's bound of the o-th derivative
    of a degree-d polynomial on [-1, 1] relative to its supremum (0 for o > d)."""
    out = 1.0
    for j in range(order):
        out *= max(degree * degree - j * j, 0) / (2 * j + 1)
    return out


def degree_bounds(S: np.ndarray, degrees: np.ndarray, angle, half, fourth: bool = False) -> tuple[np.ndarray, ...]:
    """Bounds of |d^2 J|, |d^3 J| (and |d^4 J| with ``fourth``): m x m x n x n, m x m x m x n x n, ...
    from sup |J_ab| <= S (n x n), each entry's degree in each coordinate (``degrees``: n x n x m; 0
    where the entry does not depend on it, so its derivatives there are 0), whether a coordinate is
    an angle, and a prismatic coordinate's half travel (Bernstein per angle, Markov per length,
    module docstring). Cost m^4 n^2 at most."""
    m = degrees.shape[-1]
    mk = np.vectorize(markov_factor, otypes=[float])
    orders = (2, 3, 4) if fourth else (2, 3)
    top = max(orders)
    # factor[k][o]: the bound of the o-th derivative in coordinate k relative to the sup, per entry (n x n)
    factor = [[np.asarray(degrees[..., k], dtype=float) ** o if angle[k] else mk(degrees[..., k], o) / float(half[k]) ** o
               for o in range(top + 1)] for k in range(m)]
    out = []
    for o in orders:
        w = np.empty((m,) * o + S.shape)
        for t in itertools.product(range(m), repeat=o):
            if any(t[i] > t[i + 1] for i in range(o - 1)):
                continue
            value = S * (1 + 1e-12)
            for k in set(t):
                value = value * factor[k][t.count(k)]
            for perm in set(itertools.permutations(t)):
                w[perm] = value
        out.append(w)
    return tuple(out)


def supremum_matrix(J: sp.Matrix, deps, spans) -> np.ndarray:
    """S (n x n) with |J_ab(theta)| <= S_ab for every theta: angles over the whole turn (as
    Bernstein's inequality needs), lengths over ``spans`` (module docstring, item 1)."""
    n = J.rows
    boxes = {}
    for c, span in zip(deps, spans):
        boxes[c.symbol] = (-4.0, 4.0) if c.angle else span   # any interval of width >= 2 pi: cos, sin in [-1, 1]
    flat = [J[i, j] for i in range(n) for j in range(i, n)]
    ivs = iter(interval_bounds(flat, boxes))
    S = np.zeros((n, n))
    for i in range(n):
        for j in range(i, n):
            lo, hi = next(ivs)
            S[i, j] = S[j, i] = max(abs(lo), abs(hi))
    d = np.sqrt(np.diag(S))
    return np.minimum(S, np.outer(d, d) * (1 + 1e-12))
