"""Error bounds of the generated API, entry point by entry point.

:mod:`derive.codegen.accuracy` bounds a straight-line computation; this
module wires the kernels as the glue does (templates/c/arm.c.jinja, the
Python module) and as :class:`derive.codegen.reference.Reference` replicates
it: a voltage limit clips u (a 1-Lipschitz map, so the unclipped bound still
holds near the limit), holds the integrator, and the observer is fed the
applied u. A state carried from step to step (the integral of e, the
observer state z, the momentum observer's m) enters with an error bound b, propagated through the exact
Jacobian A of the step in the state: b_next = |A| b + l, l the step's own
rounding bound (Higham, sec. 3.3, applied per step).

Carried over a sequence, b_{k+1} = |A_k| b_k + l_k loses the cancellation that makes A_k contract:
where some |A_k| has a Perron root above 1 (a 12-joint chain's observer step: the off-diagonal
entries of dt W J^-1 add up), the bound grows geometrically in the steps while the error does
not (snake12: a relative error "up to 7.3e+71" in double). There the error set is carried as a
zonotope instead (:class:`Zonotope`: e_k in {G_k xi : |xi| <= 1}, G_{k+1} = [A_k G_k, diag(l_k)]),
absolute values taken only for the bound of each step, so b_k <= sum_j |A_{k-1} ... A_{j+1}| l_j:
the same first-order model, never looser, and polynomial (its generators are capped).

Where a clip decision lies within the bound of its limit, the generated code
may decide either way: the bound then covers both branches (for the held
integrator, the jump dt e). Everything is batched: K points at once, arrays
of shape (K, ...); n joints, x = (theta, theta', yd, yd', yd'') of 5 n.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from derive.codegen.accuracy import CONST, KernelModel, Tape, weights
from derive.codegen.casadi_bridge import to_function
from derive.codegen.kernels import ParamsMode, kernel_specs
from derive.control.pipeline import Derivation

_X = ("theta", "dtheta", "yd", "dyd", "ddyd")


@dataclass(frozen=True)
class StepBounds:
    """One step of a stateful entry point at K points: values (double) and bounds, (K, n) each."""

    u: np.ndarray           # applied u (after the limits)
    u_bound: np.ndarray
    next: np.ndarray        # next state
    next_bound: np.ndarray
    ambiguous: np.ndarray   # (K,) a clip decision within the bound of its limit


@dataclass(frozen=True)
class _Entry:
    tape: Tape
    outputs: tuple[int, ...]
    wrt: tuple[int, ...]
    sizes: tuple[int, ...]


class Zonotope:
    """A set {G xi : |xi|_inf <= 1} of n-vectors (G: n x g), for carrying an error bound through a
    linear recursion with its cancellations. Past CAP n generators the smallest (1-norm) are boxed:
    replaced by diag(sum of their |g|), n generators that contain them (Girard's order reduction),
    so a step costs O(CAP n^3)."""

    CAP = 16

    def __init__(self, n: int) -> None:
        self.G = np.zeros((n, 0))

    def bound(self) -> np.ndarray:
        """The interval hull: |e_i| <= sum_j |G_ij|."""
        return np.abs(self.G).sum(axis=1)

    def image(self, A: np.ndarray) -> np.ndarray:
        """The bound of A e over the set: sum_j |(A G)_ij| (<= |A| times the bound)."""
        return np.abs(A @ self.G).sum(axis=1)

    def reset(self, b: np.ndarray) -> None:
        """The box |e| <= b (after a step bounded by other means)."""
        self.G = np.diag(np.asarray(b, float))

    def step(self, A: np.ndarray, add: np.ndarray, hold: np.ndarray | None = None) -> None:
        """e -> A e + d, |d| <= add (rows ``hold`` kept as they were: a held integrator)."""
        G = A @ self.G
        if hold is not None and hold.any():
            G[hold] = self.G[hold]
        add = np.asarray(add, float)
        nz = np.flatnonzero(add)
        new = np.zeros((G.shape[0], nz.size))
        new[nz, np.arange(nz.size)] = add[nz]
        G = np.hstack([G, new])
        n = G.shape[0]
        if G.shape[1] > self.CAP * n:
            order = np.argsort(np.abs(G).sum(axis=0), kind="stable")
            small = order[:G.shape[1] - (self.CAP - 1) * n]
            G = np.hstack([G[:, np.sort(order[small.size:])], np.diag(np.abs(G[:, small]).sum(axis=1))])
        self.G = G


def contracts(A: np.ndarray) -> bool:
    """Whether every |A_k| of the stack (steps x n x n) has its Perron root at most 1: the entrywise
    recursion b_{k+1} = |A_k| b_k + l_k does not grow geometrically (module docstring)."""
    if A.shape[0] == 0:
        return True
    return bool(np.abs(np.linalg.eigvals(np.abs(A))).max() <= 1.0 + 1e-12)


class ApiBounds:
    """First-order rounding bounds of the generated entry points of one arm
    for one real type. ``exact_inputs``: the inputs are exact in that type
    (the self-test's dyadic vectors); otherwise each carries one rounding."""

    def __init__(self, d: Derivation, real: str, mode: ParamsMode = ParamsMode.BAKED, exact_inputs: bool = True,
                 u_max: Sequence[float] | None = None, observer: str = "explicit"):
        self.n = n = d.n
        self.implicit = observer == "implicit"   # dobc_step's bounds: explicit step only (testvectors.IMPLICIT_RULE)
        self.w = weights(real, exact_inputs)
        self.u_max = np.array(u_max if u_max is not None else [
            float(m.input_limit) if m.input_limit is not None else 0.0 for m in d.arm.motors])
        self._specs = {s.name: s for s in kernel_specs(d, mode, observer)}
        models = {name: KernelModel(s) for name, s in self._specs.items()}
        params = [float(v) for _, v in d.values] if mode is ParamsMode.RUNTIME else []

        def start() -> tuple[Tape, dict]:
            t = Tape()
            x = t.leaf("x", 5 * n)
            ports = {name: x[k * n:(k + 1) * n] for k, name in enumerate(_X)}
            ports["int_e"] = ports["z"] = ports["m"] = t.leaf("s", n)
            ports["dt"] = t.leaf("dt", 1)
            ports["p"] = [t.constant(v) for v in params]
            return t, ports

        def call(t: Tape, name: str, ports: dict) -> list[list[int]]:
            return t.kernel(models[name], ports)

        self._entries: dict[str, _Entry] = {}
        self._last: dict = {}
        for name in ("gains", "mpc", "dobc_init", "npid", "mom_init"):
            t, ports = start()
            outs = call(t, name, ports)
            self._entries[name] = _Entry(t, tuple(v for o in outs for v in o), tuple(ports["z"]),
                                         tuple(len(o) for o in outs))
        t, ports = start()   # mom_estimate: the second output of the mom kernel
        dhat = call(t, "mom", ports)[1]
        self._entries["mom_dhat"] = _Entry(t, tuple(dhat), tuple(ports["z"]), (n,))
        for form, law, step in (("dobc", "dobc", "observer"), ("mom", "mom", "mom_next")):
            t, ports = start()   # the law, the limits (a select), then the state's step fed the applied u
            outs = call(t, law, ports)   # the law's further outputs feed the step by port name
            u = outs[0]
            keep, clip = t.leaf("keep", n, kind=None), t.leaf("clip", n, kind=CONST)
            applied = [t.select(keep[i], u[i], clip[i]) for i in range(n)]
            named = {p.name: o for p, o in zip(self._specs[law].outputs[1:], outs[1:])}
            if form == "dobc" and "dobc_factor" in self._specs:   # J's factor, as on a clipped step: unclipped,
                (named["ldl"],) = call(t, "dobc_factor", {**ports, **named})   # it multiplies u - u_law = 0
            (s_next,) = call(t, step, {**ports, **named, "u_law": u, "u": applied})
            self._entries[form] = _Entry(t, (*u, *s_next), tuple(ports["z"]), (n, n))

    def operations(self, name: str) -> int:
        """The size (CasADi nodes) of kernel ``name``: K of the coarse float rule."""
        return int(to_function(self._specs[name]).n_nodes())

    def _eval(self, name: str, x, s=None, dt=0.0, keep=None, clip=None):
        """Per output port: values (K, size), bounds (K, size), Jacobians in the state (K, size, n)."""
        e, n = self._entries[name], self.n
        x = np.atleast_2d(np.asarray(x, float))
        K = x.shape[0]
        inputs = {"x": x.T, "s": (np.zeros((K, n)) if s is None else np.atleast_2d(np.asarray(s, float))).T,
                  "dt": np.full((1, K), float(dt))}
        if name in ("dobc", "mom"):
            inputs["keep"] = (np.ones((K, n)) if keep is None else keep).T
            inputs["clip"] = (np.zeros((K, n)) if clip is None else clip).T
        if name == "gains":
            inputs["x"] = np.vstack([x.T[:n], np.zeros((4 * n, K))]) if x.shape[1] == n else x.T
        values, bound, jac = e.tape.evaluate(inputs, e.outputs, e.wrt, self.w)
        out, k = [], 0
        for size in e.sizes:
            out.append((values[k:k + size].T, bound[k:k + size].T, np.moveaxis(jac[k:k + size], 2, 0)))
            k += size
        return out

    def gains(self, theta) -> np.ndarray:
        """Bounds on P, D, I (row-major, (K, 3 n^2)) at K angle vectors (K, n)."""
        return np.hstack([b for _, b, _ in self._eval("gains", theta)])

    def dobc_init(self, x, dt: float = 0.0) -> np.ndarray:
        """Bounds on z(0), (K, n) (``dt``: the sample time of an implicit build's dobc_init)."""
        return self._eval("dobc_init", x, dt=dt)[0][1]

    def mom_init(self, x) -> np.ndarray:
        """Bounds on the momentum observer's m(0) = J theta', (K, n)."""
        return self._eval("mom_init", x)[0][1]

    def mom_estimate(self, m, x) -> np.ndarray:
        """Bounds on dhat = B^-1 K (J theta' - m) from exact states m (K, n), (K, n)."""
        return self._eval("mom_dhat", x, m)[0][1]

    def _clip(self, u_raw: np.ndarray, b_raw: np.ndarray):
        """(applied u, its bound, limited, near a limit) for the voltage limits."""
        lim = self.u_max
        limited = (lim > 0) & (np.abs(u_raw) > lim)
        near = (lim > 0) & (np.abs(np.abs(u_raw) - lim) <= b_raw)
        u = np.where(limited, np.sign(u_raw) * lim, u_raw)
        b_lim = lim * self.w[CONST]
        bound = np.where(near, np.maximum(b_raw, b_lim), np.where(limited, b_lim, b_raw))
        return u, bound, limited, near

    def mpc_step(self, x) -> np.ndarray:
        """Bounds on the applied u of mpc_step, (K, n)."""
        u_raw, b_raw, _ = self._eval("mpc", x)[0]
        return self._clip(u_raw, b_raw)[1]

    def _steps(self, form: str, states, xs, dt):
        """The steps of ``form`` at K points, each from an exact state: a dict of
        arrays (kept: the reference's propagation and the tolerances evaluate
        the same 1000 steps)."""
        states, xs = np.atleast_2d(np.asarray(states, float)), np.atleast_2d(np.asarray(xs, float))
        key = (form, states.tobytes(), xs.tobytes(), float(dt))
        if key in self._last:
            return self._last[key]
        self._last[key] = ev = self._uncached_steps(form, states, xs, dt)
        return ev

    def _uncached_steps(self, form: str, states: np.ndarray, xs: np.ndarray, dt):
        (u_raw, l_raw, A_raw), (nxt, l_next, A_next) = self._eval(form, xs, states, dt)
        limited = (self.u_max > 0) & (np.abs(u_raw) > self.u_max)
        ev = {"state": states, "x": xs, "dt": dt, "u_raw": u_raw, "l_raw": l_raw, "A_raw": A_raw,
              "next": nxt, "l_next": l_next, "A_next": A_next, "limited": limited}
        if form in ("dobc", "mom") and limited.any():  # the observer is fed the limited u
            (_, _, _), (nxt, l_next, A_next) = self._eval(form, xs, states, dt, (~limited).astype(float),
                                                          np.sign(u_raw) * self.u_max)
            ev.update({"next": nxt, "l_next": l_next, "A_next": A_next})
        return ev

    def _combine(self, form: str, ev: dict, k: slice, b: np.ndarray) -> StepBounds:
        """Bounds of the steps ``k`` of ``ev`` from states whose errors are bounded by b (rows)."""
        u_raw, limited = ev["u_raw"][k], ev["limited"][k]
        b_raw = np.einsum("kij,kj->ki", np.abs(ev["A_raw"][k]), b) + ev["l_raw"][k]
        b_step = np.einsum("kij,kj->ki", np.abs(ev["A_next"][k]), b) + ev["l_next"][k]
        u, b_u, _, near = self._clip(u_raw, b_raw)
        state, nxt = ev["state"][k], ev["next"][k]
        if form == "npid":  # the integrator is held at a limit
            nxt, b_next = np.where(limited, state, nxt), np.where(limited, b, b_step)
            b_next = np.where(near, np.maximum(b, b_step) + np.abs(ev["next"][k] - state), b_next)
        else:
            b_next = b_step
            for row in np.flatnonzero(near.any(axis=1)):  # the other decision at the rows in doubt
                keep = ev["limited"][k][row] == near[row]
                clip = np.sign(u_raw[row]) * self.u_max
                (_, _, _), (alt, l_alt, A_alt) = self._eval(form, ev["x"][k][row], state[row], ev["dt"],
                                                            keep[None, :].astype(float), clip[None, :])
                b_alt = np.abs(A_alt[0]) @ b[row] + l_alt[0]
                b_next[row] = np.maximum(b_step[row], b_alt) + np.abs(alt[0] - nxt[row])
        return StepBounds(u, b_u, nxt, b_next, near.any(axis=1))

    def npid_step(self, int_e, x, dt, b_state=None) -> StepBounds:
        """NPID steps from int_e (K, n), whose error is bounded by ``b_state`` (default exact)."""
        ev = self._steps("npid", int_e, x, dt)
        b = np.zeros_like(ev["u_raw"]) if b_state is None else np.atleast_2d(b_state)
        return self._combine("npid", ev, slice(None), b)

    def dobc_step(self, z, x, dt, b_state=None) -> StepBounds:
        """DOBC steps from z (K, n), whose error is bounded by ``b_state`` (default exact)."""
        ev = self._steps("dobc", z, x, dt)
        b = np.zeros_like(ev["u_raw"]) if b_state is None else np.atleast_2d(b_state)
        return self._combine("dobc", ev, slice(None), b)

    def mom_step(self, m, x, dt, b_state=None) -> StepBounds:
        """Momentum-observer steps from m (K, n), whose error is bounded by ``b_state`` (default exact)."""
        ev = self._steps("mom", m, x, dt)
        b = np.zeros_like(ev["u_raw"]) if b_state is None else np.atleast_2d(b_state)
        return self._combine("mom", ev, slice(None), b)

    def sequence(self, form: str, states, xs, dt) -> tuple[np.ndarray, np.ndarray, bool]:
        """Bounds on the last u and on the final state after the steps of
        ``form`` ('npid', 'dobc' or 'mom') along the reference trajectory:
        ``states[k]`` the state before step k, ``xs[k]`` its input. The steps
        are evaluated at once, then the state's bound is carried step by step.
        Returns (u bound, final state bound, a clip decision was in doubt)."""
        ev = self._steps(form, states, xs, dt)
        lim = self.u_max
        if not contracts(ev["A_next"]):
            return self._zonotope_sequence(form, ev)
        A_raw, A_next, l_raw, l_next = np.abs(ev["A_raw"]), np.abs(ev["A_next"]), ev["l_raw"], ev["l_next"]
        gap, limited = np.abs(np.abs(ev["u_raw"]) - lim), ev["limited"]
        b_lim = lim * self.w[CONST]
        b = np.zeros(self.n)
        doubt = False
        b_u = b
        for k in range(len(ev["x"])):
            b_raw = A_raw[k] @ b + l_raw[k]
            if ((lim > 0) & (gap[k] <= b_raw)).any():   # a clip decision in doubt: both branches (_combine)
                step = self._combine(form, ev, slice(k, k + 1), b[None, :])
                b_u, b, doubt = step.u_bound[0], step.next_bound[0], True
                continue
            b_u = np.where(limited[k], b_lim, b_raw)   # _combine with no decision in doubt
            b_step = A_next[k] @ b + l_next[k]
            b = np.where(limited[k], b, b_step) if form == "npid" else b_step
        return b_u, b, doubt


    def propagate(self, form: str, states, xs, dt, r_u, r_s) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on the last u and the final state when step k itself errs by
        at most r_u[k] (its u) and r_s[k] (its next state), propagated with the
        steps' exact Jacobians: the accumulated error of another evaluation
        of the same steps (the reference's, whose local radii are r)."""
        ev = self._steps(form, states, xs, dt)
        e = np.zeros(self.n)
        e_u = e
        if not contracts(ev["A_next"]):   # the error set as a zonotope (module docstring)
            Z = Zonotope(self.n)
            for k in range(len(ev["x"])):
                e_u = Z.image(ev["A_raw"][k]) + r_u[k]
                Z.step(ev["A_next"][k], r_s[k], ev["limited"][k] if form == "npid" else None)
            return e_u, Z.bound()
        for k in range(len(ev["x"])):
            e_u = np.abs(ev["A_raw"][k]) @ e + r_u[k]
            moved = np.abs(ev["A_next"][k]) @ e
            e = (np.where(ev["limited"][k], e, moved) if form == "npid" else moved) + r_s[k]
        return e_u, e

    def _zonotope_sequence(self, form: str, ev: dict) -> tuple[np.ndarray, np.ndarray, bool]:
        """:meth:`sequence` with the state's error set carried as a :class:`Zonotope`; a step whose
        clip decision is in doubt is bounded by :meth:`_combine` on the set's box, which restarts it."""
        lim = self.u_max
        gap, limited = np.abs(np.abs(ev["u_raw"]) - lim), ev["limited"]
        b_lim = lim * self.w[CONST]
        Z = Zonotope(self.n)
        doubt = False
        b_u = np.zeros(self.n)
        for k in range(len(ev["x"])):
            b_raw = Z.image(ev["A_raw"][k]) + ev["l_raw"][k]
            if ((lim > 0) & (gap[k] <= b_raw)).any():
                step = self._combine(form, ev, slice(k, k + 1), Z.bound()[None, :])
                b_u, doubt = step.u_bound[0], True
                Z.reset(step.next_bound[0])
                continue
            b_u = np.where(limited[k], b_lim, b_raw)
            held = limited[k] if form == "npid" else None   # a held integrator: its error as it was
            Z.step(ev["A_next"][k], ev["l_next"][k] if held is None else np.where(held, 0.0, ev["l_next"][k]), held)
        return b_u, Z.bound(), doubt


def relative(bound, values) -> float:
    """Norm-wise relative size of a bound: max bound / max |value| (0 or inf when the values are 0)."""
    scale = float(np.max(np.abs(values))) if np.size(values) else 0.0
    top = float(np.max(bound)) if np.size(bound) else 0.0
    return top / scale if scale > 0 else (0.0 if top == 0 else float("inf"))
