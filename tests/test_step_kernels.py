"""The observers' steps computed from the law's quantities (issue 23): J theta' and C^T theta' by one
recursion (derive.dynamics.momentum), the DOBC's J y = G - B u - W theta' - z by y = -a - J^-1 B (u - u_law)
with the LDL^T factor of J (derive.codegen.ldl), checked against the reference forms (J and the
Coriolis matrix formed, a general solve) with joints clipped and not."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derive
from derive.codegen.casadi_bridge import to_function
from derive.codegen.kernels import ParamsMode, kernel_specs
from derive.codegen.ldl import factor_symbols, ldl_factor, ldl_solve
from derive.dynamics.equations import derive_dynamics
from derive.dynamics.program import dag_xreplace
from derive.dynamics.sx import batched

URDF = Path(__file__).resolve().parent / "data" / "urdf"


@pytest.mark.parametrize("arm", [None, "panda", "synthetic", "kinova"])
def test_momentum_recursion_gives_J_dq_and_the_coriolis_transpose_times_dq(arm):
    """(J q', C^T q') of derive.dynamics.momentum against J (CRBA) times q' and the transposed
    Christoffel-consistent Coriolis matrix times q' at 40 states: the default arm, the Panda, an
    arm with a prismatic joint (synthetic) and one with axes off the coordinate axes (kinova)."""
    dyn = derive_dynamics(derive.load_arm(None if arm is None else URDF / f"{arm}.toml"))
    s, n = dyn.sym, dyn.n
    p, ct = dyn.momentum
    C = dyn.coriolis
    want = list(dyn.J * sp.Matrix(s.dtheta)) + [sum((C[j, i] * s.dtheta[j] for j in range(n)), sp.S.Zero)
                                               for i in range(n)]
    f = batched(list(s.theta + s.dtheta), dag_xreplace(want + list(p) + list(ct), dyn.subs))
    Y = f(np.random.default_rng(23).uniform(-2.5, 2.5, (40, 2 * n)))
    scale = max(1.0, float(np.abs(Y[:, :2 * n]).max()))
    assert np.abs(Y[:, :2 * n] - Y[:, 2 * n:]).max() <= 1e-13 * scale


def test_ldl_factor_and_solve_as_generated_code_computes_them_solve_spd_systems():
    """The factor of a symbolic symmetric 7 x 7 matrix and the solve with it, through CasADi as the
    kernels are built, against numpy's solve at 50 random positive definite matrices (condition
    numbers up to about 1e4): relative error within 1e-11."""
    n = 7
    a = sp.symbols(f"a1:{n * (n + 1) // 2 + 1}", real=True)
    k = iter(a)
    A = sp.zeros(n, n)
    for i in range(n):
        for j in range(i + 1):
            A[i, j] = A[j, i] = next(k)
    b = sp.symbols(f"b1:{n + 1}", real=True)
    factor = ldl_factor(A)
    x = ldl_solve(factor_symbols(n), sp.Matrix(b)).xreplace(dict(zip(factor_symbols(n), factor)))
    f = batched(list(a) + list(b), list(x))
    rng = np.random.default_rng(5)
    rows, want = [], []
    for _ in range(50):
        Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
        M = Q @ np.diag(np.logspace(0, rng.uniform(0, 4), n)) @ Q.T
        rhs = rng.normal(size=n)
        rows.append([M[i, j] for i in range(n) for j in range(i + 1)] + list(rhs))
        want.append(np.linalg.solve(M, rhs))
    got, want = f(np.array(rows)), np.array(want)
    assert np.abs(got - want).max(axis=1).max() <= 1e-11 * np.abs(want).max()


@pytest.fixture(scope="module")
def panda():
    return derive.derive(derive.load_arm(URDF / "panda.toml"))


def test_panda_observer_steps_with_and_without_clipped_joints_match_the_reference_forms(panda):
    """dobc -> limits -> observer and mom -> limits -> mom_next (the kernels, as the glue wires them)
    against eq. (21) with a general solve of J y = G - B u - W theta' - z and against
    m + dt (B u + C^T theta' - g - F theta' + K (J theta' - m)) with the Coriolis matrix, at the applied
    u: unclipped, and with half the joints limited to half their |u|."""
    d = panda
    n = d.n
    specs = {k.name: k for k in kernel_specs(d, ParamsMode.BAKED)}
    law, factor, obs = (to_function(specs[k]) for k in ("dobc", "dobc_factor", "observer"))
    mom, mom_next = to_function(specs["mom"]), to_function(specs["mom_next"])
    s = d.dynamics.sym
    mo = d.momentum
    beta = d.numeric(mo.beta)
    ref = batched(list(s.theta + s.dtheta), list(d.J) + list(d.G) + list(beta) + list(d.numeric(mo.p)))
    W, B = np.array(d.W, dtype=float), np.array(d.B, dtype=float)
    K = np.diag([float(v) for k, v in d.values if k in set(mo.k)])
    rng = np.random.default_rng(2023)
    dt = 1e-3
    for trial in range(12):
        x = np.concatenate([rng.uniform(-2, 2, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-2, 2, n),
                            rng.uniform(-1, 1, n), rng.uniform(-3, 3, n)])
        xs = [x[k * n:(k + 1) * n] for k in range(5)]
        z, m = rng.uniform(-5, 5, n), rng.uniform(-2, 2, n)
        row = ref(x[None, :2 * n])[0]
        J, G = row[:n * n].reshape(n, n), row[n * n:n * n + n]
        beta_v, p = row[n * n + n:n * n + 2 * n], row[n * n + 2 * n:]
        for clip in (False, True):
            def limit(u):
                u = np.array(u, dtype=float).ravel()
                if clip:
                    u[::2] = 0.5 * u[::2]   # joints 1, 3, 5, 7 held at half their u
                return u
            u_law, a, trig = (np.array(v, dtype=float).ravel() for v in law(*xs, z))
            # J's sines and cosines: of joints 2-7 (J never depends on the first joint's angle)
            np.testing.assert_allclose(trig, [f(q) for q in xs[0][1:] for f in (np.sin, np.cos)], rtol=1e-15,
                                       atol=1e-15)
            ldl = np.array(factor(xs[0], trig), dtype=float).ravel()
            v = limit(u_law)
            got = np.array(obs(z, a, ldl, u_law, v, dt), dtype=float).ravel()
            want = z + dt * W @ np.linalg.solve(J, G - B @ v - W @ xs[1] - z)
            assert np.abs(got - want).max() <= 1e-10 * max(1.0, np.abs(want).max()), (trial, clip)
            if not clip:   # unclipped, the glue passes a zero factor (J's multiplies u - u_law = 0)
                zero = np.array(obs(z, a, np.zeros_like(ldl), u_law, v, dt), dtype=float).ravel()
                np.testing.assert_array_equal(zero, got)
            u_mom, _, rate = (np.array(v_, dtype=float).ravel() for v_ in mom(*xs, m))
            v = limit(u_mom)
            got = np.array(mom_next(m, rate, u_mom, v, dt), dtype=float).ravel()
            want = m + dt * (B @ v + beta_v + K @ (p - m))
            assert np.abs(got - want).max() <= 1e-10 * max(1.0, np.abs(want).max()), (trial, clip)
