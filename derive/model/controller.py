"""The [controller] table of an arm file (eq. 14-19, 23-25 and the momentum observer): the Controller it
becomes, its keys, the observer gain W in its three forms and the runtime parameters of T1, T2, W and K."""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import sympy as sp

from derive.model.chain import Parameter
from derive.model.fields import ANY, NONNEGATIVE, POSITIVE, Num, Reader, domain, fmt, inline, show
from derive.model.rules import division_free_det, horizon

T1_SYMBOL, T2_SYMBOL = sp.Symbol("T1", **domain(NONNEGATIVE["s"])), sp.Symbol("T2", **domain(POSITIVE["s"]))
_MISSING = object()   # a key the file leaves out (a sentinel: TOML has no null)
_ZERO = Fraction(0)


OBSERVER_STRUCTURES = ("chen", "full")


OBSERVER_STEPS = ("explicit", "implicit")   # controller.observer: the default of --observer (derive.codegen.kernels)


@dataclass(frozen=True)
class Controller:
    """Settings of the predictive controller (eq. 14-19) and observer (eq. 23-25).

    The observer gain W [N m s/rad: p = W theta' is a joint torque, eq. 22] is given one of
    three ways: ``w`` (n gains, ``W[i][j] = w_j``
    for j <= i, eq. 25 generalised), ``W`` (a full n x n matrix) or ``w_auto`` (chosen by
    derive.control.certificate.synthesis for the box ``max_joint_speed`` and the rate ``observer_rate``,
    with the structure ``observer_structure``: "chen" or "full"). ``observer_rate``
    [1/s]: the exponential rate the observer certificate must give (0: any).
    ``momentum_gain``: the diagonal gain K [1/s] of the generalized-momentum observer
    (form mom, derive.control.momentum: r' = K (B d - r)), one per joint; empty when the
    arm file does not give it (MOMENTUM_GAIN for every joint). ``observer``: the observer step the
    commands build by default (their ``--observer``): "explicit" (forward Euler of eq. 21) or
    "implicit" (backward Euler; ``derive init`` writes it where only it allows a usable sample time).
    """

    T1: Fraction
    T2: Fraction
    w: tuple[Fraction, ...] | None
    C: tuple[tuple[Fraction, ...], ...]
    max_joint_speed: tuple[Fraction, ...] | None
    W: tuple[tuple[Fraction, ...], ...] | None = None
    w_auto: bool = False
    observer_rate: Fraction = Fraction(0)
    observer_structure: str = "chen"
    momentum_gain: tuple[Fraction, ...] = ()   # K of the momentum observer [1/s]; () = MOMENTUM_GAIN each
    observer: str = "explicit"   # the observer step of the commands' default build (OBSERVER_STEPS)


def w_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Observer gain symbols w1..wn (eq. 25)."""
    return tuple(sp.Symbol(f"w{i + 1}", positive=True) for i in range(n))


def full_w_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Gain symbols of a full W, row-major: W1_1, W1_2, ..., Wn_n [N m s/rad]."""
    return tuple(sp.Symbol(f"W{i + 1}_{j + 1}", real=True) for i in range(n) for j in range(n))


MOMENTUM_GAIN = Fraction(50)   # 1/s: the default K_i of the momentum observer (time constant 20 ms)


def momentum_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Gain symbols kr1..krn [1/s] of the momentum observer, K = diag(kr) (derive.control.momentum)."""
    return tuple(sp.Symbol(f"kr{i + 1}", **domain(MOMENTUM)) for i in range(n))


def momentum_parameters(c: "Controller") -> tuple[Parameter, ...]:
    """K of the momentum observer as parameters kr1..krn (the arm file's, else MOMENTUM_GAIN)."""
    gains = c.momentum_gain or (MOMENTUM_GAIN,) * len(c.C)
    return tuple(Parameter(s, v, "1/s", f"controller.momentum_gain[{i}]",
                           f"momentum observer gain K{i}: r' = K (B d - r) (form mom)")
                 for i, (s, v) in enumerate(zip(momentum_symbols(len(gains)), gains), 1))


def gain_unit(prismatic: tuple[bool, ...], i: int, j: int) -> str:
    """The unit of W[i][j] (0-based): p = W theta' is a generalized force (z + p = B dhat, eq. 22,
    a joint torque in both actuations), so W[i][j] is joint i's force unit times s per joint j's
    coordinate unit: N m s/rad between revolute joints (N s/m between prismatic ones)."""
    return f"{'N' if prismatic[i] else 'N m'} s/{'m' if prismatic[j] else 'rad'}"


def gain_units_text(prismatic: tuple[bool, ...]) -> str:
    """W's unit in words: "N m s/rad" (every joint revolute), "N s/m" (every joint prismatic), else
    per entry (:func:`gain_unit`)."""
    if len(set(prismatic)) == 1:
        return gain_unit(prismatic, 0, 0)
    return "W[i][j] in joint i's force unit s per joint j's coordinate unit (N m s/rad, N m s/m, N s/rad, N s/m)"


def observer_parameters(w=None, W=None, field: str = "controller.w",
                        prismatic: tuple[bool, ...] | None = None) -> tuple[Parameter, ...]:
    """The observer gain as parameters: w1..wn (eq. 25 pattern) or W1_1..Wn_n (a full W), each with
    its unit (:func:`gain_unit`; ``prismatic``: which joints are prismatic, default none; w_j has the
    unit of the diagonal entry W[j][j])."""
    n = len(W) if W is not None else len(w)
    kinds = prismatic if prismatic is not None else (False,) * n
    if W is not None:
        return tuple(Parameter(s, W[k // n][k % n], gain_unit(kinds, k // n, k % n),
                               f"{field}[{k // n + 1}][{k % n + 1}]",
                               f"observer gain W[{k // n + 1}][{k % n + 1}] (full W, eq. 23-25)")
                     for k, s in enumerate(full_w_symbols(n)))
    return tuple(Parameter(s, v, gain_unit(kinds, i - 1, i - 1), f"{field}[{i}]", f"observer gain w{i} (eq. 25)")
                 for i, (s, v) in enumerate(zip(w_symbols(len(w)), w), 1))


def controller_parameters(c: Controller, prismatic: tuple[bool, ...] | None = None) -> tuple[Parameter, ...]:
    """T1, T2 (eq. 14), the observer gain (eq. 25; none here for w = "auto": the
    pipeline adds the synthesised one) and the momentum observer's K as parameters;
    k1, k2 are expressions of T1, T2. ``prismatic``: which joints are prismatic (W's units)."""
    out = [Parameter(T1_SYMBOL, c.T1, "s", "controller.T1", "minimum prediction time T1 (eq. 14)"),
           Parameter(T2_SYMBOL, c.T2, "s", "controller.T2", "maximum prediction time T2 (eq. 14)")]
    if not c.w_auto:
        out += observer_parameters(c.w, c.W, prismatic=prismatic)
    return tuple(out) + momentum_parameters(c)


CONTROLLER_KEYS = {"T1": NONNEGATIVE["s"].expected, "T2": POSITIVE["s"].expected,
                   "w": "an array of observer gains, one per joint (eq. 25)", "C": None, "max_joint_speed": None,
                   "observer_rate": None, "observer_structure": None, "momentum_gain": None,
                   "observer": None}


W_EXPECTED = ("an array of n observer gains w_j > 0 [N m s/rad] (W[i][j] = w_j for j <= i, eq. 25), an n x n array "
              "(a full W), or 'auto' (chosen by an SDP for max_joint_speed)")


RATE = Num("1/s", _ZERO)


MOMENTUM = Num("1/s", _ZERO, True)   # controller.momentum_gain[i] > 0


def _controller(r: Reader, value: Any, n: int | None) -> Controller | None:
    f = "controller"
    d = None if value is _MISSING else r.table(value, f, CONTROLLER_KEYS, "a table [controller] with T1, T2 and w")
    if d is None:
        return None
    T1, T2 = r.number(d, "T1", f, NONNEGATIVE["s"]), r.number(d, "T2", f, POSITIVE["s"])
    if T1 is not None and T2 is not None and not horizon(T1_SYMBOL, T2_SYMBOL).holds({T1_SYMBOL: T1, T2_SYMBOL: T2}):
        shown = show(d["T2"]) + (f" (= {fmt(T2)})" if isinstance(d["T2"], str) else "")
        r.add("controller.T2", f"a number > T1 = {fmt(T1)} (s; the prediction horizon [T1, T2] of eq. 14)", shown)
    w, W, auto = _observer_gain(r, d, n)
    speeds = _vector(r, d, "max_joint_speed", n, POSITIVE["rad/s"])
    momentum = _vector(r, d, "momentum_gain", n, MOMENTUM)
    rate = r.number(d, "observer_rate", f, RATE, _ZERO)
    structure = d.get("observer_structure", "chen")
    if structure not in OBSERVER_STRUCTURES or ("observer_structure" in d and not auto):
        r.add("controller.observer_structure", "'chen' or 'full', with w = 'auto' (the structure of the "
              "synthesised W)", show(structure) + ("" if auto else " (w is not 'auto')"))
    step = d.get("observer", "explicit")
    if step not in OBSERVER_STEPS:
        r.add("controller.observer", "'explicit' or 'implicit' (the observer step the commands build by default)",
              show(step))
    if auto and "max_joint_speed" not in d:
        r.add("controller.max_joint_speed", "the speed box [rad/s] W is synthesised for (w = 'auto')",
              "nothing (the key is missing)")
    C = _matrix(r, d.get("C"), n)
    if None in (T1, T2, rate) or not (w or W or auto) or (speeds and None in speeds) or (momentum and None in momentum):
        return None
    return Controller(T1, T2, w, C, tuple(speeds) if speeds else None, W=W, w_auto=auto, observer_rate=rate,
                      momentum_gain=tuple(momentum) if momentum else (),
                      observer_structure=structure if structure in OBSERVER_STRUCTURES else "chen",
                      observer=step if step in OBSERVER_STEPS else "explicit")


def _observer_gain(r: Reader, d: dict, n: int | None) -> tuple[tuple | None, tuple | None, bool]:
    """(w, W, auto) from controller.w: n gains w_j > 0, an n x n matrix, or 'auto'.

    Whether the observer converges is the certificate's to decide (derive check); what is
    checked here is what every certificate needs: a positive diagonal of W (the diagonal
    of W + W^T) and an invertible W (V of (a7) uses W^-1)."""
    if "w" not in d:
        return None, None, False
    value = d["w"]
    if isinstance(value, str) and value == "auto":
        return None, None, True
    if isinstance(value, list) and value and all(isinstance(row, list) for row in value):
        m = n if n is not None else len(value)
        if len(value) != m or not all(len(row) == m for row in value):
            r.bad("controller.w", W_EXPECTED, value)
            return None, None, False
        rows = [[r.value(x, f"controller.w[{i}][{j}]", ANY["1/s"]) for j, x in enumerate(row, 1)]
                for i, row in enumerate(value, 1)]
        if any(x is None for row in rows for x in row):
            return None, None, False
        bad = [i for i in range(m) if rows[i][i] <= 0]
        for i in bad:
            r.add(f"controller.w[{i + 1}][{i + 1}]", "a diagonal entry > 0 [N m s/rad] (W + W^T must be positive "
                  "definite)", show(value[i][i]))
        if not bad and division_free_det(rows, _ZERO) == 0:
            r.add("controller.w", "an invertible W (V of eq. a7 uses W^-1)", f"{inline(value)} (det W = 0)")
            return None, None, False
        return (None, tuple(tuple(row) for row in rows), False) if not bad else (None, None, False)
    if not isinstance(value, list) or not value or (n is not None and len(value) != n) \
            or any(isinstance(x, list) for x in value):
        r.bad("controller.w", W_EXPECTED.replace("n observer", f"{n} observer") if n else W_EXPECTED, value)
        return None, None, False
    w = [r.value(x, f"controller.w[{i}]", ANY["1/s"]) for i, x in enumerate(value, 1)]
    if None in w:
        return None, None, False
    bad = [i for i, x in enumerate(w) if x <= 0]
    for i in bad:
        r.add(f"controller.w[{i + 1}]", f"w{i + 1} > 0 (observer gain [N m s/rad]: the diagonal of W + W^T, eq. 25)",
              show(value[i]))
    return (None if bad else tuple(w)), None, False


def _vector(r: Reader, d: dict, key: str, n: int | None, num: Num) -> list | None:
    """An array of one number per joint (its entries named key[1], key[2], ...)."""
    if key not in d:
        return None
    value, field = d[key], f"controller.{key}"
    if not isinstance(value, list) or not value or (n is not None and len(value) != n):
        count = "n numbers" if n is None else f"{n} number{'' if n == 1 else 's'}"
        r.bad(field, f"an array of {count}, one per joint", value)
        return None
    return [r.value(x, f"{field}[{i}]", num) for i, x in enumerate(value, 1)]


def _matrix(r: Reader, value: Any, n: int | None) -> tuple[tuple[Fraction, ...], ...]:
    """C of y = C theta (eq. 13): n x n and invertible; the identity when not given."""
    identity = tuple(tuple(Fraction(int(i == j)) for j in range(n)) for i in range(n or 0))
    if value is None:
        return identity
    m = n if n is not None else (len(value) if isinstance(value, list) else 0)
    if (not isinstance(value, list) or m == 0 or len(value) != m
            or not all(isinstance(row, list) and len(row) == m for row in value)):
        r.bad("controller.C", f"a {m or 'n'} x {m or 'n'} array of numbers "
              "(the output matrix of y = C theta, eq. 13)", value)
        return identity
    rows = [[r.value(x, f"controller.C[{i}][{j}]", ANY[""]) for j, x in enumerate(row, 1)]
            for i, row in enumerate(value, 1)]
    if any(x is None for row in rows for x in row):
        return identity
    if division_free_det(rows, _ZERO) == 0:
        r.add("controller.C", "an invertible matrix (u* of eq. 15 uses C^-1)",
              f"the singular matrix {inline(value)} (det C = 0)")
        return identity
    return tuple(tuple(row) for row in rows)
