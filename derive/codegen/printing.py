"""Print a CasADi Function's instruction list as C99 or Python statements.

CasADi has already shared subexpressions and allocated work registers; this
module only spells each instruction in the target language, with the chosen
real type: for float, every literal carries an ``f`` suffix and every libm
call is the float variant (``sinf``), so no double arithmetic is emitted.
Instructions outside the table raise, so no unknown operation is ever printed.

C gets one statement per instruction (the compiler allocates registers). Python,
where every statement costs interpreter time, gets the same operations as fewer
statements (:func:`_python_statements`): each value a name of its own, constants
written where they are used, and a value used once written into the expression
that uses it (parenthesised: the same operations in the same order, so the same
IEEE double results as one statement per instruction).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from derive.control.ranges import normal_range, range_problem
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
    ca.OP_FLOOR: ("floor{f}({0})", "_floor({0})"),   # a continuous joint's error wrap (derive.control.sampling.wrap)
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


_TRIG = {ca.OP_SIN: "trig_sin({0})", ca.OP_COS: "trig_cos({0})"}   # own_trig (derive.codegen.trig)


@dataclass(frozen=True)
class Printed:
    """A kernel's body: register count, statements, and operation count; ``arrays``: the
    local arrays the statements use besides the registers (C declarators, e.g. ``ts0[6]``)."""

    registers: int
    statements: tuple[str, ...]
    operations: int
    unused_inputs: tuple[str, ...]
    arrays: tuple[str, ...] = ()


def expected_literal(value: float, real: str) -> str:
    """A self-test's expected value as c_literal writes it, except that a value below the
    smallest normal number of ``real`` (an entry that is 0 but for the reference's last
    digits, e.g. 1.7e-48 in a regressor column) is written 0: the self-tests compare within
    tolerances far above it (norm-wise relative, or per entry at least the rounding of want)."""
    if value != 0 and np.isfinite(value) and abs(value) < normal_range(real)[0]:
        value = 0.0
    return c_literal(value, real)


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


_NESTING = 24   # the deepest expression a value used once is folded into (Python's parser has a limit)


def _python_statements(f: ca.Function, ins: tuple[str, ...], outs: tuple[str, ...]) -> list[str]:
    """Python statements computing ``f``: every value defined once (``a<k>``, numbered in order),
    constants as literals where they are used, an input read once and a value used once folded
    into the expression that uses it (up to _NESTING deep), anything else assigned to its name;
    last, each output port a list literal of its entries (``u = [..., ...]``; 0.0 for an entry
    no instruction writes)."""
    # pass 1: values (one per instruction that defines a register), their uses
    defs: list[tuple[int, int, tuple[int, ...]]] = []   # (instruction, op, operand values)
    current: dict[int, int] = {}                         # register -> the value it holds
    uses: list[int] = []
    stores: list[tuple[int, int, int]] = []             # (output port, index, value)
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        args = f.instruction_input(k)
        if op == ca.OP_OUTPUT:
            uses[current[args[0]]] += 1
            stores.append((*f.instruction_output(k), current[args[0]]))
            continue
        if op in (ca.OP_INPUT, ca.OP_CONST):
            operands: tuple[int, ...] = ()
        else:
            if op not in _OPS:
                raise DerivationError(f"kernel {f.name()}: CasADi operation {op} has no printer")
            operands = tuple(current[a] for a in args)
            for a, v in enumerate(operands):
                uses[v] += _OPS[op][1].count("{%d}" % a)
        current[f.instruction_output(k)[0]] = len(defs)
        defs.append((k, op, operands))
        uses.append(0)
    # pass 2: expressions; (text, atomic, depth) per value
    text: list[tuple[str, bool, int]] = []
    lines: list[str] = []

    def operand(v: int) -> tuple[str, int]:
        t, atomic, depth = text[v]
        return (t, 0) if atomic else (f"({t})", depth)

    for v, (k, op, operands) in enumerate(defs):
        if op == ca.OP_CONST:
            lit = py_literal(f.instruction_constant(k))
            text.append((lit, not lit.startswith("-"), 0))
            continue
        if op == ca.OP_INPUT:
            port, index = f.instruction_input(k)
            expr, depth = f"{ins[port]}[{index}]", 0
        else:
            parts = [operand(a) for a in operands]
            expr = _OPS[op][1].format(*(p[0] for p in parts))
            depth = 1 + max((p[1] for p in parts), default=0)
        if uses[v] == 1 and depth < _NESTING:
            text.append((expr, op == ca.OP_INPUT, depth))
        else:
            lines.append(f"a{v} = {expr}")
            text.append((f"a{v}", True, 0))
    entries = [["0.0"] * f.nnz_out(port) for port in range(f.n_out())]
    for port, index, v in stores:
        entries[port][index] = text[v][0]
    return lines + [f"{outs[port]} = [{', '.join(e)}]" for port, e in enumerate(entries)]


def _hoisted_trig(f: ca.Function) -> tuple[dict[tuple[int, int], None], dict[int, tuple[int, int]], set[int]]:
    """The input entries (port, index) whose sine or cosine ``f`` takes directly, in order (a dict
    as an ordered set); the sin and cos instructions that take them (instruction -> entry); and the
    input loads (instruction numbers) whose value something else reads (the others are not
    printed: their entry goes to trig_sincos)."""
    holds: dict[int, tuple[tuple[int, int], int]] = {}   # register -> (input entry, its load)
    entries: dict[tuple[int, int], None] = {}
    takes: dict[int, tuple[int, int]] = {}
    used: set[int] = set()
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        args = f.instruction_input(k)
        if op not in (ca.OP_INPUT, ca.OP_CONST):
            for a in (args[:1] if op == ca.OP_OUTPUT else args):
                if a in holds:
                    if op in (ca.OP_SIN, ca.OP_COS):
                        entries.setdefault(holds[a][0])
                        takes[k] = holds[a][0]
                    else:
                        used.add(holds[a][1])
        if op == ca.OP_OUTPUT:
            continue
        reg = f.instruction_output(k)[0]
        if op == ca.OP_INPUT:
            holds[reg] = (tuple(args), k)
        else:
            holds.pop(reg, None)
    return entries, takes, used


def trig_runs(indices: list[int], size: int) -> list[tuple[int, int]]:
    """Runs (first entry, count) of an input port of ``size`` entries (at least two) whose lanes
    cover ``indices``, every count even (trig_sincos_n works in pairs of lanes:
    derive.codegen.trig): pairs (i, i + 1) from each index not yet covered, (i - 1, i) for the
    port's last entry, consecutive pairs merged."""
    starts: list[int] = []
    for i in sorted(indices):
        if starts and i < starts[-1] + 2:
            continue
        starts.append(i if i + 1 < size else i - 1)
    runs: list[tuple[int, int]] = []
    for a in starts:
        if runs and runs[-1][0] + runs[-1][1] == a:
            runs[-1] = (runs[-1][0], runs[-1][1] + 2)
        else:
            runs.append((a, 2))
    return runs


def print_function(f: ca.Function, language: str, real: str = "double",
                   inputs: tuple[str, ...] | None = None, outputs: tuple[str, ...] | None = None,
                   own_trig: bool = False, lone_pair: bool = False) -> Printed:
    """Statements computing ``f``; inputs and outputs are addressed as ``<port>[k]`` by port
    name (C arrays or Python sequences). C: one statement per instruction, registers ``a0..``;
    Python: the same operations as fewer statements (:func:`_python_statements`).

    ``own_trig`` (C): sin and cos call the file's own (derive.codegen.trig.c_helper) instead of
    libm. Those of input entries are computed first, so that they overlap with the rest of the
    kernel: a port's several angles at once, one ``trig_sincos_n(theta + 1, ts0, tc0, 6)`` per
    run of lanes (:func:`trig_runs`), straight from the input array (no copy: a vector load of
    two scalar stores would stall), into the local arrays ``ts<j>``, ``tc<j>``
    (``Printed.arrays``); a port's lone angle by ``trig_sincos`` (both at once) into two
    registers of their own, or with ``lone_pair`` (a file whose other kernels call
    trig_sincos_n: one copy of the polynomials per file) by trig_sincos_n on a pair of its port.
    The entry's load is printed only when something else reads it."""
    ins = inputs or tuple(f.name_in())
    outs = outputs or tuple(f.name_out())
    suffix = "f" if real == "float" else ""
    one = c_literal(1.0, real)
    lines: list[str] = []
    ops = 0
    read: set[int] = set()
    hoisted, takes, loads = _hoisted_trig(f) if own_trig and language == "c" else ({}, {}, set())
    lane: dict[tuple[int, int], tuple[int, int]] = {}   # input entry -> (trig_sincos_n call, lane)
    trig_reg: dict[tuple[tuple[int, int], int], int] = {}   # a lone angle: (entry, OP_SIN / OP_COS) -> register
    arrays: list[str] = []
    taken = set(ins) | set(outs)
    for port in dict.fromkeys(p for p, _ in hoisted):
        indices = [i for p, i in hoisted if p == port]
        read.add(port)
        if len(indices) == 1 and (not lone_pair or f.nnz_in(port) == 1):   # trig_sincos, into two registers
            entry = (port, indices[0])
            for op in (ca.OP_SIN, ca.OP_COS):
                trig_reg[entry, op] = f.sz_w() + len(trig_reg)
            lines.append(f"trig_sincos({ins[port]}[{indices[0]}], &a{trig_reg[entry, ca.OP_SIN]}, "
                         f"&a{trig_reg[entry, ca.OP_COS]});")
            continue
        for start, count in trig_runs(indices, f.nnz_in(port)):
            j = len(arrays) // 2
            names = (f"ts{j}", f"tc{j}")
            if taken & set(names):
                raise DerivationError(f"kernel {f.name()}: a port is named like a sine array ({names})")
            arrays += [f"{names[0]}[{count}]", f"{names[1]}[{count}]"]
            source = f"{ins[port]} + {start}" if start else ins[port]
            lines.append(f"trig_sincos_n({source}, {names[0]}, {names[1]}, {count});")
            for i in indices:
                if start <= i < start + count:
                    lane.setdefault((port, i), (j, i - start))
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        args = f.instruction_input(k)
        res = f.instruction_output(k)
        if k in takes and takes[k] in lane:
            j, i = lane[takes[k]]
            lines.append(f"a{res[0]} = t{'s' if op == ca.OP_SIN else 'c'}{j}[{i}];")
            ops += 1
        elif k in takes:
            lines.append(f"a{res[0]} = a{trig_reg[takes[k], op]};")
            ops += 1
        elif op == ca.OP_INPUT:
            if hoisted and k not in loads:
                continue   # its entry only goes to the trig call
            read.add(args[0])
            lines.append(f"a{res[0]} = {ins[args[0]]}[{args[1]}];")
        elif op == ca.OP_OUTPUT:
            lines.append(f"{outs[res[0]]}[{res[1]}] = a{args[0]};")
        elif op == ca.OP_CONST:
            if language == "c":
                lines.append(f"a{res[0]} = {c_literal(f.instruction_constant(k), real)};")
        else:
            try:
                template = _TRIG[op] if own_trig and op in _TRIG else _OPS[op][0]
            except KeyError:
                raise DerivationError(f"kernel {f.name()}: CasADi operation {op} has no printer") from None
            lines.append(f"a{res[0]} = " + template.format(*(f"a{a}" for a in args), f=suffix, one=one) + ";")
            ops += 1
    if language != "c":
        lines = _python_statements(f, ins, outs)
    unused = tuple(name for i, name in enumerate(ins) if i not in read)
    return Printed(registers=f.sz_w() + len(trig_reg), statements=tuple(lines), operations=ops,
                   unused_inputs=unused, arrays=tuple(arrays))
