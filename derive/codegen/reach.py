"""Which kernel inputs a non-finite value reaches a checked output from (the C glue's input checks).

A step of the generated C returns ENONFINITE for a non-finite input, state or result
(templates/c/arm.c.jinja). It always checks the kernel's results (their exponent bits, which no
compiler flag can fold away). An input entry needs no check of its own when a non-finite value
there is sure to make a checked result non-finite. This module proves that for each input port
of each kernel, on the kernel's CasADi instruction list, the very list the C is printed from:

* **Propagation (IEEE evaluation).** Every operation below gives a non-finite result when the
  operand marked is non-finite: ``x + y``, ``x - y``, ``x * y`` (Inf * 0 is NaN), ``-x``, ``x * x``,
  ``x + x``, ``fabs``, ``floor``, ``sqrt`` (of -Inf: NaN), ``sin`` and ``cos`` (NaN; the C file's
  own helper sends a non-finite argument to libm, derive.codegen.trig), and the numerator of
  ``x / y``. A result takes the union of its propagating operands' entries; anything else
  (a denominator, ``fmin``, a comparison, ``exp``, ``tanh``, ...) takes none. An entry reaches an
  output when the output's value carries it: then a non-finite entry gives a non-finite output.
* **Real dependence (flags that assume finite math).** ``-ffast-math`` may rewrite the arithmetic
  by identities of real numbers (reassociation, x - x = 0), which could drop an operand the output
  does not really depend on. So each entry must also move the output: some entry of the output
  port's Jacobian column for it is at least ``RELATIVE`` times the Jacobian's largest entry, at a
  fixed generic point (:func:`generic_point`), the Jacobian of the output in all the kernel's inputs. An output that depends on the entry somewhere is
  not constant in it, so no rewrite exact in real arithmetic removes it.

A port is covered by an output port when every one of its entries passes both; the glue then
leaves out that port's own check (tests/test_finite_math.py runs the error contract under ten
flag sets that assume finite math, with link-time optimisation).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import casadi as ca
import numpy as np

# operation -> the operand positions whose non-finite value makes the result non-finite
PROPAGATES: dict[int, tuple[int, ...]] = {
    ca.OP_ASSIGN: (0,), ca.OP_ADD: (0, 1), ca.OP_SUB: (0, 1), ca.OP_MUL: (0, 1), ca.OP_NEG: (0,),
    ca.OP_SQ: (0,), ca.OP_TWICE: (0,), ca.OP_FABS: (0,), ca.OP_FLOOR: (0,), ca.OP_SQRT: (0,),
    ca.OP_SIN: (0,), ca.OP_COS: (0,), ca.OP_DIV: (0,),
}
RELATIVE = 1e-9   # a Jacobian column below this share of the largest entry is not taken as a dependence


def carried(f: ca.Function) -> list[list[int]]:
    """Per output port, per entry: a bit set (Python int) of the input entries whose non-finite
    value makes that entry non-finite under IEEE evaluation of ``f``'s instruction list (module
    docstring). Input entry (port p, index i) is bit ``offset(p) + i``, ports in order."""
    offsets = np.cumsum([0] + [f.nnz_in(p) for p in range(f.n_in())]).tolist()
    reg: dict[int, int] = {}
    out = [[0] * f.nnz_out(p) for p in range(f.n_out())]
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        args = f.instruction_input(k)
        if op == ca.OP_OUTPUT:
            port, index = f.instruction_output(k)
            out[port][index] = reg[args[0]]
            continue
        if op == ca.OP_INPUT:
            port, index = args
            bits = 1 << (offsets[port] + index)
        elif op == ca.OP_CONST:
            bits = 0
        else:
            bits = 0
            for a in PROPAGATES.get(op, ()):
                bits |= reg[args[a]]
        reg[f.instruction_output(k)[0]] = bits
    return out


def generic_point(f: ca.Function, values: Mapping[str, Sequence[float]] | None = None) -> list[np.ndarray]:
    """A fixed point to evaluate ``f`` at, one array per input port: ``values[name]`` where given
    (the arm's parameters), else entries 0.3 + 0.4 frac(0.618 (k + 1)) (no zeros, no symmetry
    between entries), a port named ``dt`` 1e-3 s."""
    point = []
    k = 0
    for p in range(f.n_in()):
        name, size = f.name_in(p), f.nnz_in(p)
        if values is not None and name in values:
            point.append(np.asarray(values[name], dtype=float))
        elif name == "dt":
            point.append(np.full(size, 1e-3))
        else:
            point.append(np.array([0.3 + 0.4 * math.modf(0.6180339887 * (k + i + 1))[0] for i in range(size)]))
        k += size
    return point


def covered(f: ca.Function, values: Mapping[str, Sequence[float]] | None = None) -> dict[str, tuple[str, ...]]:
    """output port name -> the input port names (in ``f``'s order) every entry of which both
    propagates to that output and moves it (module docstring); ``values``: input ports to fix
    at given values for the dependence test (a runtime build's parameters)."""
    bits = carried(f)
    offsets = np.cumsum([0] + [f.nnz_in(p) for p in range(f.n_in())]).tolist()
    point = generic_point(f, values)
    sx_in = f.sx_in()
    sx_out = f.call(sx_in)
    result: dict[str, tuple[str, ...]] = {}
    jac = ca.Function("reach_jacobian", sx_in, [ca.jacobian(out, ca.vertcat(*sx_in)) for out in sx_out])
    jacobians = [np.abs(np.asarray(J, dtype=float)) for J in jac.call(point)]
    for o in range(f.n_out()):
        union = 0
        for b in bits[o]:
            union |= b
        J = jacobians[o]
        moves = J.max(axis=0) >= RELATIVE * J.max() if J.size and J.max() > 0 and np.all(np.isfinite(J)) \
            else np.zeros(J.shape[1], dtype=bool)
        result[f.name_out(o)] = tuple(
            f.name_in(p) for p in range(f.n_in())
            if f.nnz_in(p) and all(union >> i & 1 and moves[i] for i in range(offsets[p], offsets[p + 1])))
    return result
