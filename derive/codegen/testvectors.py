"""Self-test vectors: inputs chosen exactly representable in float and double
(multiples of 2^-10), expected outputs from the high-precision reference of the
SymPy derivation (derive.codegen.reference), never from the generated code.

Tolerances (norm-wise relative error per output vector, ||got - ref||_inf /
||ref||_inf): double 1e-12; float ``float_bound(K, steps)`` = 16 (K + steps) 2^-24,
the first-order rounding bound gamma_K of K operations in single precision
(Higham, Accuracy and Stability, 3.1) with a factor 16 for cancellation, plus
one rounding per Euler step of a sequence.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from derive.codegen.reference import Reference

DOUBLE_TOL = 1e-12
SEQUENCE_STEPS = 1000
SEQUENCE_DT = 2.0 ** -10


def float_bound(operations: int, steps: int = 0) -> float:
    """Stated bound on the norm-wise relative error of float results."""
    return 16.0 * (operations + steps) * 2.0 ** -24


def _dyadic(rng: np.random.Generator, low: float, high: float, size: int) -> list[float]:
    return [round(v * 1024) / 1024 for v in rng.uniform(low, high, size)]


@dataclass(frozen=True)
class Case:
    """One state and every expected output at it (floats)."""

    x: tuple[float, ...]        # theta, dtheta, yd, dyd, ddyd
    int_e: tuple[float, ...]
    z: tuple[float, ...]
    gains: tuple[float, ...]    # P, D, I row-major
    mpc: tuple[float, ...]
    npid_u: tuple[float, ...]
    npid_next: tuple[float, ...]
    dobc_u: tuple[float, ...]
    dobc_next: tuple[float, ...]
    z0: tuple[float, ...]


def sequence_input(k: int, n: int) -> list[float]:
    """Input at step k of the self-test sequence: dyadic, the same formula in C."""
    out = []
    for block in range(5):
        for i in range(n):
            m = (k * (2 * i + 3 + block) + 17 * i + 5 * block) % 129
            out.append(m / 128.0 - 0.5)
    return out


def cases(ref: Reference, count: int, seed: int = 20261122) -> tuple[Case, ...]:
    """``count`` random cases (fixed seed) with reference outputs at dt = SEQUENCE_DT."""
    rng = np.random.default_rng(seed)
    n = ref.n
    out = []
    for _ in range(count):
        x = (_dyadic(rng, -3.0, 3.0, n) + _dyadic(rng, -3.0, 3.0, n) + _dyadic(rng, -3.0, 3.0, n)
             + _dyadic(rng, -2.0, 2.0, n) + _dyadic(rng, -5.0, 5.0, n))
        int_e, z = _dyadic(rng, -1.0, 1.0, n), _dyadic(rng, -1.0, 1.0, n)
        nu, nn = ref.npid_step(int_e, x, SEQUENCE_DT)
        du, dn = ref.dobc_step(z, x, SEQUENCE_DT)
        f = lambda v: tuple(float(a) for a in v)  # noqa: E731
        out.append(Case(tuple(x), tuple(int_e), tuple(z), f(ref.gains(x[:n])), f(ref.mpc_step(x)),
                        f(nu), f(nn), f(du), f(dn), f(ref.dobc_init(x))))
    return tuple(out)


def sequence(ref: Reference, steps: int = SEQUENCE_STEPS) -> dict[str, tuple[float, ...]]:
    """Final u and state after ``steps`` steps of each form from init."""
    n = ref.n
    x0 = sequence_input(0, n)
    int_e = [0] * n
    z = ref.dobc_init(x0)
    nu = du = None
    for k in range(steps):
        x = sequence_input(k, n)
        nu, int_e = ref.npid_step(int_e, x, SEQUENCE_DT)
        du, z = ref.dobc_step(z, x, SEQUENCE_DT)
    f = lambda v: tuple(float(a) for a in v)  # noqa: E731
    return {"npid_u": f(nu), "int_e": f(int_e), "dobc_u": f(du), "z": f(z)}
