"""Print a CasADi Function's instruction list as C99 or Python statements.

CasADi has already shared subexpressions and allocated work registers; this
module only spells each instruction in the target language, with the chosen
real type: for float, every literal carries an ``f`` suffix and every libm
call is the float variant (``sinf``), so no double arithmetic is emitted.
Instructions outside the table raise, so no unknown operation is ever printed.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from derive.control.ranges import range_problem
from derive.errors import DerivationError

# op -> (C template, Python template); {0}, {1}: operand registers, {f}: libm suffix
_OPS: dict[int, tuple[str, str]] = {
    ca.OP_ASSIGN: ("{0}", "{0}"),
    ca.OP_ADD: ("{0} + {1}", "{0} + {1}"),
    ca.OP_SUB: ("{0} - {1}", "{0} - {1}"),
    ca.OP_MUL: ("{0} * {1}", "{0} * {1}"),
    ca.OP_DIV: ("{0} / {1}", "{0} / {1}"),
    ca.OP_NEG: ("-{0}", "-{0}"),
    ca.OP_TWICE: ("{0} + {0}", "{0} + {0}"),
    ca.OP_SQ: ("{0} * {0}", "{0} * {0}"),
    ca.OP_INV: ("{one} / {0}", "1.0 / {0}"),
    ca.OP_SIN: ("sin{f}({0})", "_sin({0})"),
    ca.OP_COS: ("cos{f}({0})", "_cos({0})"),
    ca.OP_TAN: ("tan{f}({0})", "_tan({0})"),
    ca.OP_TANH: ("tanh{f}({0})", "_tanh({0})"),
    ca.OP_SQRT: ("sqrt{f}({0})", "_sqrt({0})"),
    ca.OP_FABS: ("fabs{f}({0})", "abs({0})"),
    ca.OP_EXP: ("exp{f}({0})", "_exp({0})"),
    ca.OP_LOG: ("log{f}({0})", "_log({0})"),
    ca.OP_FLOOR: ("floor{f}({0})", "_floor({0})"),   # a continuous joint's error wrap (derive.control.wrap)
    ca.OP_POW: ("pow{f}({0}, {1})", "{0} ** {1}"),
    ca.OP_CONSTPOW: ("pow{f}({0}, {1})", "{0} ** {1}"),
    # the simulation plant's pulse train and amplifier (derive.fmu.plant): C's relational
    # operators give 0 or 1, as CasADi's; if_else_zero(c, x) is c ? x : 0
    ca.OP_FMOD: ("fmod{f}({0}, {1})", "_fmod({0}, {1})"),
    ca.OP_FMIN: ("fmin{f}({0}, {1})", "min({0}, {1})"),
    ca.OP_FMAX: ("fmax{f}({0}, {1})", "max({0}, {1})"),
    ca.OP_LT: ("{0} < {1}", "float({0} < {1})"),
    ca.OP_LE: ("{0} <= {1}", "float({0} <= {1})"),
    ca.OP_NOT: ("!{0}", "float(not {0})"),
    ca.OP_AND: ("{0} && {1}", "float({0} and {1})"),
    ca.OP_IF_ELSE_ZERO: ("{0} ? {1} : 0", "{1} if {0} else 0.0"),
}


@dataclass(frozen=True)
class Printed:
    """A kernel's body: register count, statements, and operation count."""

    registers: int
    statements: tuple[str, ...]
    operations: int
    unused_inputs: tuple[str, ...]


def c_literal(value: float, real: str) -> str:
    """A C literal of the real type: double with 17 significant digits, float
    rounded to single precision with an ``f`` suffix.

    Every constant of the generated C passes here: one that is not a normal number
    of ``real`` (inf, nan, beyond its range, subnormal, underflowing to 0) raises
    DerivationError. (``derive.control.ranges`` has refused such arms already,
    naming their fields; this guards every other way a constant could arrive.)"""
    if (why := range_problem(value, real)) is not None:
        raise DerivationError(f"the constant {value!r} {why}: it cannot be written into {real} code")
    if real == "float":
        text = str(np.float32(value))  # shortest text that rounds back to this float
        return (text if ("." in text or "e" in text) else text + ".0") + "f"
    text = repr(float(value))
    return text if ("." in text or "e" in text) else text + ".0"


def py_literal(value: float) -> str:
    """A Python float literal (double, repr round-trips); raises DerivationError like
    :func:`c_literal` for a value that is not a normal double."""
    if (why := range_problem(value, "double")) is not None:
        raise DerivationError(f"the constant {value!r} {why}: it cannot be written into Python code")
    return repr(float(value))


def print_function(f: ca.Function, language: str, real: str = "double",
                   inputs: tuple[str, ...] | None = None, outputs: tuple[str, ...] | None = None) -> Printed:
    """Statements computing ``f`` with registers ``a0..``; inputs and outputs are
    addressed as ``<port>[k]`` by port name (C arrays or Python sequences)."""
    ins = inputs or tuple(f.name_in())
    outs = outputs or tuple(f.name_out())
    suffix = "f" if real == "float" else ""
    one = c_literal(1.0, real)
    lines: list[str] = []
    ops = 0
    read: set[int] = set()
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        args = f.instruction_input(k)
        res = f.instruction_output(k)
        if op == ca.OP_INPUT:
            read.add(args[0])
            lines.append(f"a{res[0]} = {ins[args[0]]}[{args[1]}]")
        elif op == ca.OP_OUTPUT:
            lines.append(f"{outs[res[0]]}[{res[1]}] = a{args[0]}")
        elif op == ca.OP_CONST:
            value = f.instruction_constant(k)
            lit = c_literal(value, real) if language == "c" else py_literal(value)
            lines.append(f"a{res[0]} = {lit}")
        else:
            try:
                template = _OPS[op][0 if language == "c" else 1]
            except KeyError:
                raise DerivationError(f"kernel {f.name()}: CasADi operation {op} has no printer") from None
            regs = [f"a{a}" for a in args]
            lines.append(f"a{res[0]} = " + template.format(*regs, f=suffix, one=one))
            ops += 1
    if language == "c":
        lines = [line + ";" for line in lines]
    unused = tuple(name for i, name in enumerate(ins) if i not in read)
    return Printed(registers=f.sz_w(), statements=tuple(lines), operations=ops, unused_inputs=unused)
