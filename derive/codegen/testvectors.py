"""Self-test vectors: inputs chosen exactly representable in float and double
(multiples of 2^-10), expected outputs from the high-precision reference of the
SymPy derivation (derive.codegen.reference), never from the generated code,
each with its tolerance.

The tolerance of every element is derived from the computation
(:mod:`derive.codegen.bounds`): twice the first-order rounding bound of the
generated code at that point (the factor covers the second-order terms), plus
the rounding of the expected value itself to the real type. It follows the
arm's conditioning: tight where the arm is well conditioned, looser (and said
so per output) where J is nearly singular.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from derive.codegen.accuracy import UNIT
from derive.codegen.balls import to_float
from derive.codegen.bounds import ApiBounds, relative
from derive.codegen.reference import DIGITS, Reference, certified
from derive.errors import DerivationError

DOUBLE_TOL = 1e-12    # the README's claim for the packaged (well-conditioned) arms' single steps
SEQUENCE_STEPS = 1000
SEQUENCE_DT = 2.0 ** -10
STEP_TRIES = 3        # precisions a sequence step is tried at (each twice the last) before the whole is redone
SAFETY = 2.0          # first-order bound times this covers the second-order terms
TINY = {"double": 2.0 ** -1022, "float": 2.0 ** -126}  # underflow of one operation


def float_bound(operations: int, steps: int = 0) -> float:
    """The coarse rule the self-test used before its tolerances were derived:
    16 (K + steps) 2^-24 for K operations (Higham's gamma_K with a factor 16).
    Kept for comparisons over arbitrary trajectories that run no rounding
    analysis (the FMU tests); the self-test uses :func:`tolerance`."""
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
    m: tuple[float, ...]           # the momentum observer's state (input of mom_step, mom_estimate)
    mom0: tuple[float, ...]        # mom_init m = J theta'
    mom_u: tuple[float, ...]
    mom_next: tuple[float, ...]
    mom_dhat: tuple[float, ...]    # mom_estimate at m
    held: tuple[float, ...] = ()   # the implicit step's held voltage (input), else empty
    u0: tuple[float, ...] = ()     # the implicit step's initial held voltage (dobc_init), else empty


OUTPUTS = ("gains", "mpc", "npid_u", "npid_next", "dobc_u", "dobc_next", "z0", "mom0", "mom_u", "mom_next",
           "mom_dhat")   # the checked fields of a Case
MOM = ("mom0", "mom_u", "mom_next", "mom_dhat")   # the momentum observer's (the same step in both builds)
CHECKS = {"gains": "gains P, D, I", "mpc": "mpc_step u", "npid_u": "npid_step u", "npid_next": "npid_step int_e",
          "dobc_u": "dobc_step u", "dobc_next": "dobc_step z", "z0": "dobc_init z", "mom0": "mom_init m",
          "mom_u": "mom_step u", "mom_next": "mom_step m", "mom_dhat": "mom_estimate dhat",
          "seq_npid_u": "npid sequence u", "seq_int_e": "npid sequence int_e", "seq_dobc_u": "dobc sequence u",
          "seq_z": "dobc sequence z", "seq_mom_u": "mom sequence u", "seq_m": "mom sequence m"}
IMPLICIT_CHECKS = {"u0": "dobc_init u"}   # checked in --observer implicit builds only
IMPLICIT_RULE = ("outputs of the implicit observer step (dobc_step u and z, dobc_init u, the dobc sequence): "
                 "norm-wise |got - want| <= 1e-12 max|want| in double, 16 (K + steps) 2^-24 max|want| in float "
                 "(K operations; no derived bound for the two-vector state yet)")


@dataclass(frozen=True)
class SequenceVectors:
    """The last u and the final state of each form after the steps, from init."""

    npid_u: tuple[float, ...]
    int_e: tuple[float, ...]
    dobc_u: tuple[float, ...]
    z: tuple[float, ...]
    mom_u: tuple[float, ...]
    m: tuple[float, ...]
    npid_states: np.ndarray     # (steps, n) int_e before each step
    dobc_states: np.ndarray     # (steps, n) z before each step
    mom_states: np.ndarray      # (steps, n) the momentum observer's m before each step
    radii: np.ndarray           # (steps, 6, n) radii of the reference's u and state at each step (npid, dobc, mom)
    dt: float = SEQUENCE_DT     # the sequence's time step (sequence_dt)


def sequence_input(k: int, n: int) -> list[float]:
    """Input at step k of the self-test sequence: dyadic, the same formula in C."""
    out = []
    for block in range(5):
        for i in range(n):
            m = (k * (2 * i + 3 + block) + 17 * i + 5 * block) % 129
            out.append(m / 128.0 - 0.5)
    return out


def _proved(compute, ref: Reference, tries: int = 4):
    """``compute()`` -> list of ball vectors (or None), rerun at twice the working
    precision until it is not None and every vector is certified to DIGITS digits."""
    for _ in range(tries):
        vectors = compute()
        if vectors is not None and all(certified(v) for v in vectors):
            return vectors
        ref.prec *= 2
    raise DerivationError(f"reference vectors not certified to {DIGITS} digits at {ref.prec // 2} bits")


def _floats(v) -> tuple[float, ...]:
    return tuple(to_float(a) for a in v)


def cases(ref: Reference, count: int, seed: int = 20261122) -> tuple[Case, ...]:
    """``count`` random cases (fixed seed) with reference outputs at dt = SEQUENCE_DT
    (for the implicit observer step also a held voltage, drawn after the explicit inputs;
    the momentum observer's state m from a stream of its own, seed + 1, so the others' inputs
    are those of the forms before it)."""
    rng, rng_m = np.random.default_rng(seed), np.random.default_rng(seed + 1)
    n = ref.n
    out = []
    for _ in range(count):
        x = (_dyadic(rng, -3.0, 3.0, n) + _dyadic(rng, -3.0, 3.0, n) + _dyadic(rng, -3.0, 3.0, n)
             + _dyadic(rng, -2.0, 2.0, n) + _dyadic(rng, -5.0, 5.0, n))
        int_e, z = _dyadic(rng, -1.0, 1.0, n), _dyadic(rng, -1.0, 1.0, n)
        held = _dyadic(rng, -1.0, 1.0, n) if ref.implicit else []
        m = _dyadic(rng_m, -1.0, 1.0, n)

        def compute():
            dobc = ref.dobc_step_implicit(z, held, x, SEQUENCE_DT) if ref.implicit else ref.dobc_step(z, x,
                                                                                                   SEQUENCE_DT)
            return (ref.gains(x[:n]), ref.mpc_step(x), *ref.npid_step(int_e, x, SEQUENCE_DT), *dobc,
                    ref.dobc_init(x, SEQUENCE_DT), *((ref.dobc_held(x, SEQUENCE_DT),) if ref.implicit else ()))
        got = list(map(_floats, _proved(compute, ref)))
        u0 = got.pop() if ref.implicit else ()
        mom = list(map(_floats, _proved(lambda: (ref.mom_init(x), *ref.mom_step(m, x, SEQUENCE_DT),
                                                 ref.mom_dhat(x, m)), ref)))
        out.append(Case(tuple(x), tuple(int_e), tuple(z), *got, tuple(m), *mom, held=tuple(held), u0=u0))
    return tuple(out)


def sequence_dt(ref: Reference, steps: int = SEQUENCE_STEPS) -> float:
    """The sequence's time step: SEQUENCE_DT, halved until the forms' own forward-Euler recursions
    contract at every input of the sequence, dt lambda <= 1 for every eigenvalue lambda of W J^-1(theta_k)
    (the explicit observer, eq. 21: z steps by I - dt W J^-1) and of the momentum observer's K (1 - dt K).
    A light joint's W J^-1 of thousands of 1/s made the fixed step's z grow without bound: the Panda's
    float bound on z reached 4e28, a 2-link arm with a 0.1 g tip overflowed double. A power of two, exact
    in float and double."""
    n = ref.n
    rate = float(np.max(np.diag(np.array(ref._d.numeric(ref._d.momentum.K).tolist(), dtype=float))))
    if not ref.implicit:
        W = np.array(ref._W.tolist(), dtype=float)
        thetas = {tuple(sequence_input(k, n)[:n]) for k in range(min(steps, 129))}   # the inputs repeat every 129
        for theta in sorted(thetas):
            J = np.array([to_float(a) for a in ref.inertia(list(theta))]).reshape(n, n)
            rate = max(rate, float(np.abs(np.linalg.eigvals(np.linalg.solve(J, W.T).T)).max()))
    dt = SEQUENCE_DT
    while dt * rate > 1.0 and dt > 2.0 ** -40:
        dt /= 2
    return dt


def sequence(ref: Reference, bounds: ApiBounds, steps: int = SEQUENCE_STEPS) -> SequenceVectors:
    """Final u and state after ``steps`` steps of each form from init (npid, dobc,
    and the momentum observer mom from mom_init, the same forward-Euler step in
    both observer builds).

    The time step is :func:`sequence_dt`'s. Each step starts from the midpoints of the previous state (a ball carried
    through 1000 steps would measure interval arithmetic's overestimation,
    not the error) and its own result is certified (a step that is not is redone at twice the
    precision, kept for the steps after it: a 12-joint chain's dobc step lost its digits at step 648
    of 1000, and the whole sequence was recomputed). How the steps' radii r_k
    propagate to the end is bounded as the generated code's errors are, with
    the exact Jacobians A_k of the steps in the state (``bounds``):
    e_{k+1} <= |A_k| e_k + r_k (or its zonotope, derive.codegen.bounds). The precision is raised until that bound too
    is below 10^-DIGITS of the result."""
    n = ref.n
    dt = sequence_dt(ref, steps)

    def compute():
        int_e = [0] * n
        z = [v.mid() for v in ref.dobc_init(sequence_input(0, n), dt)]
        held = [v.mid() for v in ref.dobc_held(sequence_input(0, n), dt)] if ref.implicit else None
        m = [v.mid() for v in ref.mom_init(sequence_input(0, n))]
        nu = du = mu = None
        states = np.zeros((3, steps, n))
        radii = np.zeros((steps, 6, n))
        for k in range(steps):
            x = sequence_input(k, n)
            states[0, k], states[1, k], states[2, k] = _floats(int_e), _floats(z), _floats(m)
            for _ in range(STEP_TRIES):   # a step not certified is redone at twice the precision, kept after
                nu, int_e1 = ref.npid_step(int_e, x, dt)
                du, z1 = (ref.dobc_step_implicit(z, held, x, dt) if ref.implicit
                          else ref.dobc_step(z, x, dt))
                mu, m1 = ref.mom_step(m, x, dt)
                if all(certified(v) for v in (nu, int_e1, du, z1, mu, m1)):
                    break
                ref.prec *= 2
            else:
                return None
            int_e, z, m = int_e1, z1, m1
            radii[k] = [[to_float(v.rad()) for v in vec] for vec in (nu, int_e, du, z, mu, m)]
            int_e, z, m = [v.mid() for v in int_e], [v.mid() for v in z], [v.mid() for v in m]
            held = [v.mid() for v in du] if ref.implicit else None
        out = SequenceVectors(*map(_floats, (nu, int_e, du, z, mu, m)), *states, radii, dt)
        checked = (("npid", (0, 1), (out.npid_u, out.int_e)),) + (
            () if ref.implicit else (("dobc", (2, 3), (out.dobc_u, out.z)),)) + (   # implicit dobc: IMPLICIT_RULE
            ("mom", (4, 5), (out.mom_u, out.m)),)
        trajectory = {"npid": out.npid_states, "dobc": out.dobc_states, "mom": out.mom_states}
        for form, (iu, ist), (u, st) in checked:
            b_u, b_s = bounds.propagate(form, trajectory[form],
                                        [sequence_input(k, n) for k in range(steps)], dt,
                                        radii[:, iu], radii[:, ist])
            if relative(b_u, u) > 10.0 ** -DIGITS or relative(b_s, st) > 10.0 ** -DIGITS:
                return None
        return [out]
    return _proved(compute, ref)[0]


def tolerance(bound: np.ndarray, values: Sequence[float], real: str) -> tuple[float, ...]:
    """SAFETY x bound + the rounding of the expected value + one underflow, rounded up
    to 3 significant digits (the same literal on every machine)."""
    tol = SAFETY * np.asarray(bound) + 2 * UNIT[real] * np.abs(values) + TINY[real]
    return tuple(_round_up(float(t)) for t in tol)


def _round_up(x: float) -> float:
    if x <= 0 or not math.isfinite(x):
        return x
    e = math.floor(math.log10(x)) - 2
    return float(math.ceil(x / 10.0 ** e) * 10.0 ** e) if e > -300 else x


def rule_tolerance(values: Sequence[float], real: str, operations: int, steps: int = 0) -> tuple[float, ...]:
    """IMPLICIT_RULE: DOUBLE_TOL (double) or float_bound(operations, steps) (float) times the
    vector's largest magnitude, plus one underflow, for every element."""
    rel = DOUBLE_TOL if real == "double" else float_bound(operations, steps)
    scale = float(np.max(np.abs(values))) if len(values) else 0.0
    return tuple(_round_up(rel * scale + TINY[real]) for _ in values)


def case_tolerances(bounds: ApiBounds, cs: Sequence[Case], real: str) -> tuple[dict[str, tuple], ...]:
    """Per case, the tolerance of every element of every checked output (IMPLICIT_RULE for the
    implicit observer step's outputs)."""
    n = bounds.n
    x = np.array([c.x for c in cs])
    npid = bounds.npid_step(np.array([c.int_e for c in cs]), x, SEQUENCE_DT)
    m = np.array([c.m for c in cs])
    mom = bounds.mom_step(m, x, SEQUENCE_DT)
    rows = {"gains": bounds.gains(x[:, :n]), "mpc": bounds.mpc_step(x), "npid_u": npid.u_bound,
            "npid_next": npid.next_bound, "z0": bounds.dobc_init(x, SEQUENCE_DT), "mom0": bounds.mom_init(x),
            "mom_u": mom.u_bound, "mom_next": mom.next_bound, "mom_dhat": bounds.mom_estimate(m, x)}
    if bounds.implicit:
        ops = bounds.operations("observer") + bounds.operations("dobc")
        return tuple({**{f: tolerance(rows[f][k], getattr(c, f), real) for f in rows},
                      **{f: rule_tolerance(getattr(c, f), real, ops) for f in ("dobc_u", "dobc_next", "u0")}}
                     for k, c in enumerate(cs))
    dobc = bounds.dobc_step(np.array([c.z for c in cs]), x, SEQUENCE_DT)
    rows.update({"dobc_u": dobc.u_bound, "dobc_next": dobc.next_bound})
    return tuple({f: tolerance(rows[f][k], getattr(c, f), real) for f in OUTPUTS} for k, c in enumerate(cs))


def sequence_tolerances(bounds: ApiBounds, seq: SequenceVectors, real: str) -> dict[str, tuple]:
    """The tolerance of each element of the sequence's last u and final states."""
    n, steps = bounds.n, len(seq.npid_states)
    xs = [sequence_input(k, n) for k in range(steps)]
    nu, ns, _ = bounds.sequence("npid", seq.npid_states, xs, seq.dt)
    mu, ms, _ = bounds.sequence("mom", seq.mom_states, xs, seq.dt)   # the same step in both builds
    out = {"seq_npid_u": tolerance(nu, seq.npid_u, real), "seq_int_e": tolerance(ns, seq.int_e, real),
           "seq_mom_u": tolerance(mu, seq.mom_u, real), "seq_m": tolerance(ms, seq.m, real)}
    if bounds.implicit:
        ops = bounds.operations("observer") + bounds.operations("dobc")
        return {**out, "seq_dobc_u": rule_tolerance(seq.dobc_u, real, ops, steps),
                "seq_z": rule_tolerance(seq.z, real, ops, steps)}
    du, ds, _ = bounds.sequence("dobc", seq.dobc_states, xs, seq.dt)
    return {**out, "seq_dobc_u": tolerance(du, seq.dobc_u, real), "seq_z": tolerance(ds, seq.z, real)}


def accuracy(cs: Sequence[Case], tols: Sequence[dict], seq: SequenceVectors, seq_tols: dict) -> dict[str, float]:
    """Stated accuracy per output: the largest norm-wise relative tolerance over the vectors."""
    fields = OUTPUTS + (("u0",) if cs and cs[0].u0 else ())
    names = {**CHECKS, **IMPLICIT_CHECKS}
    out = {names[f]: max(relative(np.array(t[f]), getattr(c, f)) for c, t in zip(cs, tols)) for f in fields}
    values = {"seq_npid_u": seq.npid_u, "seq_int_e": seq.int_e, "seq_dobc_u": seq.dobc_u, "seq_z": seq.z,
              "seq_mom_u": seq.mom_u, "seq_m": seq.m}
    out.update({CHECKS[f]: relative(np.array(seq_tols[f]), values[f]) for f in values})
    return out
