"""SymPy -> CasADi SX of single expressions, by value numbering over the expression DAG.

The kernels (derive.codegen.casadi_bridge) and the observer certificate's numeric J and
its derivatives (derive.control.certificate.inertia) build their CasADi graphs through :func:`to_sx`:
each distinct subexpression is converted once. Exact rationals become the nearest double
exactly once.
"""
from __future__ import annotations

from fractions import Fraction

import casadi as ca
import sympy as sp

from derive.dynamics.dag import Memo
from derive.errors import DerivationError

_FUNCTIONS = {sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan, sp.Abs: ca.fabs, sp.exp: ca.exp,
              sp.log: ca.log, sp.tanh: ca.tanh, sp.floor: ca.floor}   # floor: a continuous joint's wrap


def _number(x: sp.Number) -> float:
    """The nearest double of an exact number (DerivationError beyond double's range)."""
    try:
        if isinstance(x, sp.Rational):
            return float(Fraction(int(x.p), int(x.q)))  # correctly rounded
        return float(x)
    except OverflowError:
        raise DerivationError(f"the constant {x} overflows double") from None


class _Sums:
    """The sums converted so far, by their terms, so that a sum containing another one's terms
    adds that sum's value instead of adding its terms again. SymPy flattens a sum of sums
    (x = a + b + c shared, then x - d is stored as a + b + c - d), so the recursions'
    shared partial sums (a body's force, a carried wrench) reach the converter as terms:
    value numbering alone would add them again in every sum that contains them.

    A term's key is (sign, what it multiplies): a + b matches the terms of -a - b with
    the opposite sign (subtracted as one value)."""

    def __init__(self) -> None:
        self.keys: list[frozenset] = []
        self.signs: list[dict] = []      # per sum: each term's key -> its sign
        self.values: list = []
        self.by_term: dict = {}

    def cover(self, terms: list) -> list[tuple[int, object, frozenset]]:
        """Greedy: the largest converted sums (sign, value, keys) whose terms, all with one
        sign flipped or none, lie in ``terms`` (a list: its order, the sum's own, decides
        ties) and in no sum taken before. Never iterates a set: a set of terms holding SymPy
        symbols has an order that depends on the process's string hash seed, and so did the
        generated code (the Panda's kernels differed between two runs)."""
        left = set(terms)
        out = []
        while len(left) >= 2:
            best = None
            for sign, key in terms:
                if (sign, key) not in left:
                    continue
                for k in self.by_term.get(key, ()):
                    keys = self.keys[k]
                    if best is not None and len(keys) <= len(best[2]):
                        continue
                    flip = sign * self.signs[k][key]
                    if all((flip * sg, ky) in left for sg, ky in keys):
                        best = (flip, self.values[k], keys, frozenset((flip * sg, ky) for sg, ky in keys))
            if best is None:
                break
            out.append((best[0], best[1], best[3]))
            left -= best[3]
        return out

    def add(self, keys: frozenset, value) -> None:
        k = len(self.keys)
        self.keys.append(keys)
        self.signs.append({key: sign for sign, key in keys})
        self.values.append(value)
        for _, key in keys:
            self.by_term.setdefault(key, []).append(k)


def _term_key(a: sp.Expr, memo: Memo) -> tuple:
    """(sign, key) of a sum's term: -x and x share the key; a product by its factors' keys."""
    sign = 1
    if a.is_Mul and a.args[0] == -1:
        sign, rest = -1, a.args[1:]
        if len(rest) == 1:
            a = rest[0]
        else:
            return sign, ("mul", tuple(memo.number(f) if f.args else f for f in rest))
    if a.is_Mul:
        return sign, ("mul", tuple(memo.number(f) if f.args else f for f in a.args))
    return sign, (memo.number(a) if a.args else a)


def _sum(expr: sp.Expr, env: dict, memo: Memo, constants: dict | None) -> ca.SX:
    """A sum, reusing the converted sums among its terms (:class:`_Sums`)."""
    sums = getattr(memo, "sx_sums", None)
    if sums is None:
        sums = memo.sx_sums = _Sums()
    keyed = {_term_key(a, memo): a for a in expr.args}
    out = None
    covered: set = set()
    for sign, value, keys in sums.cover(list(keyed)):
        covered |= keys
        out = (value if sign > 0 else -value) if out is None else (out + value if sign > 0 else out - value)
    for key, a in keyed.items():
        if key not in covered:
            t = to_sx(a, env, memo, constants)
            out = t if out is None else out + t
    sums.add(frozenset(keyed), out)
    return out


def to_sx(expr: sp.Expr, env: dict, memo: Memo, constants: dict | None = None) -> ca.SX:
    """CasADi SX of a SymPy expression; ``env`` maps symbols to SX scalars;
    ``memo`` (shared by the kernel's expressions) gives equal subexpressions
    one SX node, by value numbering (never comparing two SymPy trees).
    With ``constants`` (a dict), every number but 0 and +-1 becomes an SX
    symbol, one per value, recorded there (number -> symbol): CasADi then
    folds no constants, and the graph shows every operation the printed code
    inherits (derive.codegen.accuracy analyses that graph)."""
    hit = memo.get(id(expr))
    if hit is not None:
        return hit[1]
    key = None
    if expr.args:
        for a in expr.args:  # compound arguments first: their numbers make this node's key
            if a.args:
                to_sx(a, env, memo, constants)
        key = (expr.func, tuple(memo.number(a) if a.args else a for a in expr.args))
        number = memo.numbered(key)
        if number is not None:  # an equal subexpression is converted already
            memo.put(expr, memo.objects[number], number)
            return memo.objects[number]
    if expr.is_Symbol:
        try:
            out = env[expr]
        except KeyError:
            raise DerivationError(f"symbol {expr} has no value in the kernel") from None
    elif expr.is_NumberSymbol:   # pi (a continuous joint's wrap): the nearest double
        out = ca.SX(float(expr)) if constants is None else constants.setdefault(expr, ca.SX.sym(f"c{len(constants)}"))
    elif expr.is_Number:
        if constants is None or expr in (0, 1, -1):
            out = ca.SX(_number(expr))
        else:
            out = constants.setdefault(expr, ca.SX.sym(f"c{len(constants)}"))
    elif expr.is_Add:
        out = _sum(expr, env, memo, constants)
    elif expr.is_Mul and len(expr.args) == 2 and expr.args[0] == -1 and expr.args[1].is_Pow \
            and expr.args[1].args[1] == -1:
        # -1/x as one quotient: CasADi writes y (-1/x) as a product, y (1/x) as the quotient y/x
        out = ca.SX(-1.0) / to_sx(expr.args[1].args[0], env, memo, constants)
    elif expr.is_Mul:
        factors = [to_sx(a, env, memo, constants) for a in expr.args]
        out = factors[0]
        for f in factors[1:]:
            out = out * f
    elif expr.is_Pow:
        base, exp = expr.args
        b = to_sx(base, env, memo, constants)
        if exp.is_Integer:
            k = int(exp)
            out = b ** abs(k) if k != -1 else 1 / b
            if k < -1:
                out = 1 / out
        elif exp == sp.Rational(1, 2):
            out = ca.sqrt(b)
        else:
            out = b ** to_sx(exp, env, memo, constants)
    elif expr.func in _FUNCTIONS:
        out = _FUNCTIONS[expr.func](to_sx(expr.args[0], env, memo, constants))
    else:
        raise DerivationError(f"cannot translate {expr.func.__name__} to CasADi")
    memo.put(expr, out, memo.register(key, out) if key is not None else None)
    return out


def batched(args, exprs, values: dict | None = None):
    """A numpy function of the expressions ``exprs`` in the symbols ``args``, evaluated at many
    points at once: called with a P x len(args) array it returns the P x len(exprs) values
    (double precision). Built through CasADi (each shared subexpression once, by
    :func:`to_sx`): a 7-joint arm's laws build in milliseconds where SymPy's ``lambdify``
    printer takes seconds. ``values``: other symbols' numbers (floats), CasADi constants in the graph
    (folded where they meet: no SymPy substitution). Raises DerivationError for a symbol in neither."""
    import numpy as np

    exprs = [sp.sympify(e) for e in exprs]
    x = ca.SX.sym("x", len(args))
    env = {s: ca.SX(float(v)) for s, v in (values or {}).items()}
    env.update({a: x[i] for i, a in enumerate(args)})
    memo = Memo()
    out = ca.vertcat(*[to_sx(e, env, memo) for e in exprs]) if exprs else ca.SX(0, 1)
    f = ca.Function("f", [x], [out])
    maps: dict[int, ca.Function] = {}

    def call(X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        P = X.shape[0]
        if P not in maps:
            maps[P] = f.map(P)
        return np.asarray(maps[P](X.T)).T.reshape(P, len(exprs))

    return call
