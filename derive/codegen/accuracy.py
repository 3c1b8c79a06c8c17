"""Accuracy of the generated code: a first-order rounding-error bound per
output, derived from the kernels' own instruction lists.

Every instruction the printer emits rounds its exact result once, by a
relative error of at most u (the unit roundoff of the real type: 2^-53
double, 2^-24 float) for + - * / sqrt, and at most 1 ulp = 2u for the libm
calls (tan, exp, log, pow); negation, fabs and doubling are exact. Sine and
cosine are the C files' own (derive.codegen.trig), with the proved mixed bound
|f_hat - f| <= eps |f| + (1 + eps) eta(k), eta growing with the quadrant count
k of the argument: the term added for such a site is |dy/dv| (eps |v| + (1 + eps)
eta(k)), k bounded from the argument's value (trig.k_max).
A constant carries the rounding of its exact rational to double and then to
the real type (u + 2^-53); an input, when it is not exact in the real type,
one rounding. Writing each rounding as v_k (1 + eps_k), the error of an
output y is, to first order,

    |y_hat - y| <= sum_k |dy/dv_k| |v_k| w_k        (|eps_k| <= w_k)

(Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., sec. 3.3:
the linearised, "automatic differentiation" bound). The derivatives are
exact derivatives of the output (a reverse sweep), so cancellation along
different paths is counted as it happens: the bound follows the arm's
conditioning (an ill-conditioned J in the observer's solve) instead of a
constant. It is evaluated in double at the test points, all at once (numpy
arrays over a batch of K points).

The kernels are analysed with every number but 0 and +-1 as an input
(``casadi_bridge.to_function(spec, constants)``): CasADi then folds no
constant, and each operation the printed code inherits through a constant
CasADi folded (in a symbolic solve, say) is counted with the weight of the
real type, at least the double rounding it had.
"""
from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from derive.codegen import trig
from derive.codegen.casadi_bridge import to_function
from derive.dynamics.sx import _number
from derive.codegen.kernels import KernelSpec
from derive.errors import DerivationError

UNIT = {"double": 2.0 ** -53, "float": 2.0 ** -24}
OP, LIBM, CONST, INPUT, TRIG = range(5)   # kinds of rounding site
TRIG_K, TRIG_FIXED = 5, 6                  # weights(): eta(k) = |k| w[TRIG_K] + w[TRIG_FIXED] (k != 0)
LEAF, SELECT = -1, -2               # tape-only nodes: an external input, the glue's clip

# op -> kind of rounding of the printed instruction (None: exact); see printing._OPS
_ROUNDING = {
    ca.OP_ASSIGN: None, ca.OP_NEG: None, ca.OP_FABS: None, ca.OP_TWICE: None, ca.OP_FLOOR: None,
    ca.OP_ADD: OP, ca.OP_SUB: OP, ca.OP_MUL: OP, ca.OP_DIV: OP, ca.OP_SQ: OP, ca.OP_INV: OP, ca.OP_SQRT: OP,
    ca.OP_SIN: TRIG, ca.OP_COS: TRIG, ca.OP_TAN: LIBM, ca.OP_EXP: LIBM, ca.OP_LOG: LIBM,
    ca.OP_POW: LIBM, ca.OP_CONSTPOW: LIBM,
}


def weights(real: str, exact_inputs: bool = True) -> np.ndarray:
    """Bounds on |eps| per kind of site: operation, libm call, constant, input, own sine or
    cosine (relative part); then the sine's and cosine's eta per quadrant and fixed part."""
    u = UNIT[real]
    b = trig.bound(real)
    return np.array([u, 2 * u, u + UNIT["double"], 0.0 if exact_inputs else u, b.relative, b.per_k, b.fixed])


def _forward(op: int, a: np.ndarray, b: np.ndarray | None) -> np.ndarray:
    with np.errstate(all="ignore"):
        if op == ca.OP_ADD:
            return a + b
        if op == ca.OP_SUB:
            return a - b
        if op == ca.OP_MUL:
            return a * b
        if op == ca.OP_DIV:
            return a / b
        if op in (ca.OP_POW, ca.OP_CONSTPOW):
            return a ** b
        return {ca.OP_ASSIGN: lambda: a, ca.OP_NEG: lambda: -a, ca.OP_TWICE: lambda: a + a,
                ca.OP_SQ: lambda: a * a, ca.OP_INV: lambda: 1.0 / a, ca.OP_SQRT: lambda: np.sqrt(a),
                ca.OP_SIN: lambda: np.sin(a), ca.OP_COS: lambda: np.cos(a), ca.OP_TAN: lambda: np.tan(a),
                ca.OP_EXP: lambda: np.exp(a), ca.OP_LOG: lambda: np.log(a), ca.OP_FABS: lambda: np.abs(a),
                ca.OP_FLOOR: lambda: np.floor(a)}[op]()


def _partials(op: int, a: np.ndarray, b: np.ndarray | None, v: np.ndarray) -> tuple:
    """d v / d a (and d v / d b) of one instruction, v its value."""
    with np.errstate(all="ignore"):
        if op == ca.OP_ADD:
            return 1.0, 1.0
        if op == ca.OP_SUB:
            return 1.0, -1.0
        if op == ca.OP_MUL:
            return b, a
        if op == ca.OP_DIV:
            return 1.0 / b, -v / b
        if op == ca.OP_CONSTPOW:
            return b * a ** (b - 1), None
        if op == ca.OP_POW:
            return b * a ** (b - 1), np.log(a) * v
        return ({ca.OP_ASSIGN: 1.0, ca.OP_NEG: -1.0, ca.OP_TWICE: 2.0, ca.OP_SQ: 2 * a, ca.OP_INV: -v * v,
                 ca.OP_SQRT: 0.5 / v, ca.OP_SIN: np.cos(a), ca.OP_COS: -np.sin(a), ca.OP_TAN: 1 + v * v,
                 ca.OP_EXP: v, ca.OP_LOG: 1.0 / a, ca.OP_FABS: np.sign(a),
                 ca.OP_FLOOR: 0.0}[op],)   # floor: exact, and constant away from the integers


class KernelModel:
    """A kernel's CasADi instruction list (constants as inputs, see the module doc)."""

    def __init__(self, spec: KernelSpec):
        numbers: dict = {}
        self.f = to_function(spec, numbers)
        self.values = [_number(x) for x in numbers]
        self.name = spec.name
        self.ports = tuple(p.name for p in spec.inputs)
        self.sizes = tuple(p.size for p in spec.outputs)
        for k in range(self.f.n_instructions()):
            op = self.f.instruction_id(k)
            if op not in _ROUNDING and op not in (ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST):
                raise DerivationError(f"kernel {self.name}: CasADi operation {op} has no error model")


class Tape:
    """A straight-line computation in single-assignment form: kernels appended
    with their inputs wired to earlier nodes, the glue's clips, external
    inputs. Node k: op, argument nodes, rounding kind (None: exact)."""

    def __init__(self) -> None:
        self.op: list[int] = []
        self.args: list[tuple[int, ...]] = []
        self.kind: list[int | None] = []
        self.const: list[float] = []
        self.leaves: dict[str, list[int]] = {}

    def _node(self, op: int, args: tuple[int, ...], kind: int | None, const: float = 0.0) -> int:
        self.op.append(op)
        self.args.append(args)
        self.kind.append(kind)
        self.const.append(const)
        return len(self.op) - 1

    def leaf(self, name: str, size: int, kind: int | None = INPUT) -> list[int]:
        """An external input vector (its values given at evaluation)."""
        nodes = [self._node(LEAF, (len(self.leaves), i), kind) for i in range(size)]
        self.leaves[name] = nodes
        return nodes

    def constant(self, value: float) -> int:
        exact = value in (0.0, 1.0, -1.0)
        return self._node(ca.OP_CONST, (), None if exact else CONST, float(value))

    def select(self, mask: int, a: int, b: int) -> int:
        """a where the ``mask`` node (0 or 1 at each point) is 1, else b: the glue's clip."""
        return self._node(SELECT, (a, b, mask), None)

    def kernel(self, model: KernelModel, ports: dict[str, Sequence[int]]) -> list[list[int]]:
        """Append a kernel, its input ports wired to ``ports``; returns its output nodes per port."""
        f = model.f
        wired = [list(ports[p]) for p in model.ports] + [[self.constant(v) for v in model.values]]
        reg: list[int] = [-1] * f.sz_w()
        outs = [[-1] * size for size in model.sizes]
        for k in range(f.n_instructions()):
            op, a, r = f.instruction_id(k), f.instruction_input(k), f.instruction_output(k)
            if op == ca.OP_INPUT:
                reg[r[0]] = wired[a[0]][a[1]]
            elif op == ca.OP_OUTPUT:
                outs[r[0]][r[1]] = reg[a[0]]
            elif op == ca.OP_CONST:
                reg[r[0]] = self.constant(f.instruction_constant(k))
            else:
                reg[r[0]] = self._node(op, tuple(reg[i] for i in a), _ROUNDING[op])
        return outs

    def evaluate(self, inputs: dict[str, np.ndarray], outputs: Sequence[int], wrt: Sequence[int],
                 w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """At K points (``inputs[name]``: shape (size, K)): the outputs' values
        (m, K), their rounding bounds (m, K) and their derivatives in the
        nodes ``wrt`` (m, len(wrt), K)."""
        K = next(iter(inputs.values())).shape[1]
        order = list(self.leaves)
        val: list = [None] * len(self.op)
        for k, (op, args) in enumerate(zip(self.op, self.args)):
            if op == LEAF:
                val[k] = np.asarray(inputs[order[args[0]]][args[1]], float)
            elif op == ca.OP_CONST:
                val[k] = np.full(K, self.const[k])
            elif op == SELECT:
                m = val[args[2]]
                val[k] = np.where(m > 0.5, val[args[0]], val[args[1]])
            else:
                val[k] = _forward(op, val[args[0]], val[args[1]] if len(args) > 1 else None)
        m = len(outputs)
        adj: dict[int, np.ndarray] = {}
        for i, node in enumerate(outputs):
            adj.setdefault(node, np.zeros((m, K)))[i] += 1.0
        bound = np.zeros((m, K))
        position = {node: j for j, node in enumerate(wrt)}
        jac = np.zeros((m, len(wrt), K))
        with np.errstate(all="ignore"):
            for k in range(len(self.op) - 1, -1, -1):
                a = adj.pop(k, None)
                if a is None:
                    continue
                kind = self.kind[k]
                if kind == TRIG:
                    quadrants = trig.k_max(val[self.args[k][0]])
                    eta = np.where(quadrants > 0, quadrants * w[TRIG_K] + w[TRIG_FIXED], 0.0)
                    bound += np.abs(a) * (np.abs(val[k]) * w[TRIG] + (1 + w[TRIG]) * eta)
                elif kind is not None:
                    bound += np.abs(a * val[k]) * w[kind]
                if k in position:
                    jac[:, position[k], :] = a
                op, args = self.op[k], self.args[k]
                if op in (LEAF, ca.OP_CONST):
                    continue
                if op == SELECT:
                    mask = val[args[2]] > 0.5
                    parts = (np.where(mask, 1.0, 0.0), np.where(mask, 0.0, 1.0))
                else:
                    parts = _partials(op, val[args[0]], val[args[1]] if len(args) > 1 else None, val[k])
                for arg, p in zip(args, parts):
                    if p is None or (np.isscalar(p) and p == 0):
                        continue
                    adj[arg] = adj[arg] + a * p if arg in adj else a * p
        values = np.array([val[node] for node in outputs])
        return values, bound, jac
