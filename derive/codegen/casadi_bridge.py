"""SymPy -> CasADi SX: each KernelSpec becomes a ``casadi.Function``.

CasADi builds the expression graph, shares common subexpressions and
allocates the work registers; ``derive.codegen.printing`` then prints its instruction
list as C or Python. Exact rationals become the nearest double exactly once.
"""
from __future__ import annotations

import casadi as ca
import sympy as sp

from derive.codegen.kernels import KernelSpec
from derive.dynamics.dag import Memo
from derive.dynamics.sx import to_sx


def to_function(spec: KernelSpec, constants: dict | None = None) -> ca.Function:
    """The CasADi Function of a kernel, with its port names. With ``constants``
    (an empty dict, filled as in :func:`to_sx`) the numbers are a last input
    port ``constants``, in the dict's order."""
    inputs = [ca.SX.sym(port.name, port.size) for port in spec.inputs]
    env = {sym: inputs[k][i] for k, port in enumerate(spec.inputs) for i, sym in enumerate(port.items)}
    memo = Memo()
    for solve in spec.solves:
        A = ca.SX(solve.A.rows, solve.A.cols)
        for i in range(solve.A.rows):
            for j in range(solve.A.cols):
                A[i, j] = to_sx(solve.A[i, j], env, memo, constants)
        b = ca.vertcat(*[to_sx(v, env, memo, constants) for v in solve.b])
        y = ca.solve(A, b)
        env.update({u: y[i] for i, u in enumerate(solve.unknowns)})
    outputs = [ca.vertcat(*[to_sx(sp.sympify(v), env, memo, constants) for v in port.items])
               for port in spec.outputs]
    names = [p.name for p in spec.inputs]
    if constants is not None:
        inputs.append(ca.vertcat(*constants.values()) if constants else ca.SX(0, 1))
        names.append("constants")
    return ca.Function(spec.name, inputs, outputs, names, [p.name for p in spec.outputs], {"cse": True})
