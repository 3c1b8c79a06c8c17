"""Plain data for the templates: one frozen view per artifact.

Views hold strings, numbers and tuples only (no SymPy, no modules): the
templates lay them out and never compute. Everything numeric that a template
shows (literals, tolerances, test vectors) is computed here.
"""
from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from derive.codegen.casadi_bridge import to_function
from derive.codegen.kernels import KernelSpec, ParamsMode, kernel_specs
from derive.codegen.ldl import factor_size
from derive.control.pipeline import Derivation
from derive.control.ranges import check_ranges
from derive.errors import Problem, SpecError
from derive.model.actuators import input_word, units_text
from derive.model.spec import gain_units_text, observer_parameters
from derive.codegen.printing import c_literal, print_function, py_literal
from derive.codegen.trig import c_helper

def comment_text(text: str) -> str:
    """``text`` safe inside a C block comment and a Python docstring alike:
    printable ASCII kept, any other character and backslash or double quote
    written as its code point (U+hhhh), comment delimiters broken apart. The spec already
    rejects such text; this is the second line of defence at the edge."""
    out = "".join(ch if (" " <= ch <= "~" and ch not in '\\"') else f"U+{ord(ch):04X}" for ch in text)
    return out.replace("*/", "* /").replace("/*", "/ *")


def param_doc(p) -> str:
    """A parameter as generated code documents it: what, unit and the arm-file field
    (a derive.model.chain.Parameter)."""
    unit = f" [{p.unit}]" if p.unit else ""
    return comment_text(f"{p.doc}{unit}, from {p.field}")


@dataclass(frozen=True)
class KernelView:
    """One kernel for the templates: its C and Python signatures and bodies."""

    name: str
    doc: str
    c_args: tuple[str, ...]       # "const real theta[2]", ..., "real u[2]"
    py_args: tuple[str, ...]
    py_outputs: tuple[tuple[str, int], ...]
    registers: int
    c_body: tuple[str, ...]
    c_locals: tuple[str, ...]    # the C body's locals: registers a0.., then its arrays (ts0[6], ...)
    py_body: tuple[str, ...]
    operations: int
    unused: tuple[str, ...]      # input ports the maths does not read


@dataclass(frozen=True)
class ArmView:
    """What every template of one arm needs (all plain data)."""

    arm: str
    ARM: str
    description: str
    source_name: str
    n: int
    real: str
    runtime: bool
    params: tuple[tuple[str, str, str], ...]   # (field, C default literal, doc)
    py_params: tuple[tuple[str, str, str], ...]
    baked: tuple[str, ...]                      # "name = value unit (field)", the values a baked build holds
    u_max: tuple[str, ...]                      # C literals, 0 = no limit
    mask: str                                   # C type of the clipped-joints bitmask
    py_u_max: tuple[str, ...]
    kernels: tuple[KernelView, ...]
    k1: str
    k2: str
    observer_notes: tuple[str, ...]             # comment lines: W, its structure, how it was chosen
    sample_notes: tuple[str, ...] = ()          # the largest sample time of each form (derive generate)
    implicit: bool = False                      # --observer implicit: the backward-Euler observer step
    wrap_notes: tuple[str, ...] = ()            # comment lines: the outputs whose error is wrapped (continuous joints)
    u_word: str = "voltage"                     # what u is: voltage, torque, or input (mixed actuation)
    u_unit: str = "V"                           # its unit: V, N m, or one per motor
    ldl_size: int = 0                           # reals of the LDL^T factor of J the DOBC step passes on
    trig_size: int = 0                          # sines and cosines the dobc kernel passes to dobc_factor
    trig_helper: tuple[str, ...] = ()           # the C file's own sin and cos (derive.codegen.trig), when used


_TRIG_CALL = re.compile(r"\btrig_(sincos_n|sincos|sin|cos)\(")   # the printer's calls (printing.print_function)


def trig_helper(kernels: Sequence[KernelView], real: str, prefix: str) -> tuple[str, ...]:
    """The C text of the file's own sine and cosine (derive.codegen.trig.c_helper) when a
    kernel's body calls them, else nothing."""
    calls = {m for k in kernels for line in k.c_body for m in _TRIG_CALL.findall(line)}
    if not calls:
        return ()
    return c_helper(real, f"{prefix}_real", tuple(f for f in ("sincos", "sincos_n", "sin", "cos") if f in calls))


def mask_type(n: int, source: str = "") -> str:
    """The narrowest standard C99 unsigned type sure to hold one bit per joint; a
    SpecError beyond 64 joints."""
    if n <= 32:
        return "unsigned long"          # at least 32 bits
    if n <= 64:
        return "unsigned long long"     # at least 64 bits
    raise SpecError(source, [Problem("link", "at most 64 links (one bit each in the clipped-joints mask)",
                                     f"{n} links")])


def kernel_view(spec: KernelSpec, real: str, prefix: str, f=None, lone_pair: bool = False) -> KernelView:
    """A kernel's C and Python text; ``f``: its CasADi Function when already built; ``lone_pair``:
    see printing.print_function."""
    f = to_function(spec) if f is None else f
    c = print_function(f, "c", real, own_trig=True, lone_pair=lone_pair)
    py = print_function(f, "python")
    c_args = tuple(f"const {prefix}_real {p.name}[{p.size}]" for p in spec.inputs)
    c_args += tuple(f"{prefix}_real {p.name}[{p.size}]" for p in spec.outputs)
    return KernelView(name=spec.name, doc=spec.doc, c_args=c_args,
                      py_args=tuple(p.name for p in spec.inputs),
                      py_outputs=tuple((p.name, p.size) for p in spec.outputs),
                      registers=c.registers, c_body=c.statements, py_body=py.statements,
                      c_locals=tuple(f"a{r}" for r in range(c.registers)) + c.arrays,
                      operations=c.operations, unused=c.unused_inputs)


def kernel_views(specs: Sequence[KernelSpec], real: str, prefix: str,
                 functions: dict | None = None) -> tuple[KernelView, ...]:
    """The views of one C file's kernels (``functions``: their CasADi Functions by name, when at
    hand). A kernel's lone angle calls trig_sincos, unless another kernel of the file calls
    trig_sincos_n: then it goes through a pair as well, so that the file holds one copy of the
    polynomials (derive.codegen.trig.c_helper)."""
    fs = [(functions or {}).get(k.name) for k in specs]
    fs = [to_function(k) if f is None else f for k, f in zip(specs, fs)]
    views = tuple(kernel_view(k, real, prefix, f) for k, f in zip(specs, fs))
    calls = {m for v in views for line in v.c_body for m in _TRIG_CALL.findall(line)}
    if {"sincos", "sincos_n"} <= calls:
        views = tuple(kernel_view(k, real, prefix, f, lone_pair=True) for k, f in zip(specs, fs))
    return views


def kernel_functions(d: Derivation, mode: ParamsMode, observer: str = "explicit") -> dict:
    """name -> CasADi Function of every kernel (built once, printed for each real type and language)."""
    return {spec.name: to_function(spec) for spec in kernel_specs(d, mode, observer)}


def arm_view(d: Derivation, real: str, mode: ParamsMode, functions: dict | None = None,
             sample_time: str | None = None, observer: str = "explicit") -> ArmView:
    """The view of one arm for one real type and parameter mode (``functions``:
    the kernels' CasADi Functions from :func:`kernel_functions`, when at hand; ``sample_time``:
    the sentence of derive.control.sampling.limit_text.summary for the header, when the caller computed it;
    ``observer``: the observer step, derive.codegen.kernels.OBSERVER_STEPS).

    Raises SpecError naming the arm-file fields when a derived constant is not a normal
    ``real`` (derive.control.ranges; e.g. k1 = 3e40 of T2 = 1e-20 in float)."""
    check_ranges(d, real)
    arm = d.arm
    values = [(str(s), float(v)) for s, v in d.values]
    limits = [float(m.input_limit) if m.input_limit is not None else 0.0 for m in arm.motors]
    numbers = dict(values)
    docs = {str(p.symbol): p for p in arm.parameters}
    syn = d.synthesis
    if syn is not None:   # w = "auto": the synthesised gain (derive.control.certificate.synthesis)
        chen = syn.structure == "chen"
        docs.update({str(p.symbol): p for p in observer_parameters(
            [syn.W[j][j] for j in range(d.n)] if chen else None, None if chen else syn.W, "controller.w = 'auto'",
            arm.prismatic)})
    specs = kernel_specs(d, mode, observer)
    kernels = kernel_views(specs, real, arm.name, functions)
    baked = tuple(comment_text(f"{name} = {value!r}{' ' + docs[name].unit if docs[name].unit else ''} "
                               f"({docs[name].field})") for name, value in values)
    return ArmView(
        arm=arm.name, ARM=arm.name.upper(), description=comment_text(arm.description),
        source_name=comment_text(arm.source.replace("\\", "/").rsplit("/", 1)[-1]), n=d.n, real=real,
        runtime=mode is ParamsMode.RUNTIME,
        params=tuple((name, c_literal(v, real), param_doc(docs[name])) for name, v in values),
        py_params=tuple((name, py_literal(v), param_doc(docs[name])) for name, v in values), baked=baked,
        u_max=tuple(c_literal(v, real) for v in limits), py_u_max=tuple(py_literal(v) for v in limits),
        mask=mask_type(d.n, arm.source),
        kernels=kernels,
        k1=py_literal(float(d.K1[0, 0])), k2=py_literal(float(d.K2[0, 0])), ldl_size=factor_size(d.n),
        trig_size=sum(p.size for k in specs if k.name == "dobc_factor" for p in k.inputs if p.name == "trig"),
        trig_helper=trig_helper(kernels, real, arm.name),
        observer_notes=tuple(comment_text(x) for x in observer_notes(d)),
        sample_notes=() if sample_time is None else tuple(textwrap.wrap(comment_text("Sample time: " + sample_time + "."),
                                                                         88)),
        implicit=observer == "implicit", u_word=input_word(arm.input_units), u_unit=units_text(arm.input_units),
        wrap_notes=tuple(textwrap.wrap(comment_text(wrap_note(d)), 80)) if d.wrapped else ())


def wrap_note(d: Derivation) -> str:
    """The sentence of the generated headers on the continuous joints' wrapped error (derive.control.sampling.wrap)."""
    joints = d.dynamics.chain.joints
    cont = [f"{j + 1} ({joints[j].name})" for j in range(d.n) if joints[j].type.value == "continuous"]
    outs = ", ".join(str(i + 1) for i in d.wrapped)
    return (f"Continuous joint{'s' if len(cont) > 1 else ''} {', '.join(cont)}: the tracking error e = yd - C theta of output(s) {outs} is "
            "wrapped to (-pi, pi], e = x + 2 pi floor((pi - x) / (2 pi)) with x = yd - C theta, in every step "
            "(u*, the initial estimate, the integral of e), so a continuous joint reported at theta or at "
            "theta - 2 pi (in (-pi, pi], say, as encoders do) gives the same command; e' = yd' - C theta' is not "
            "wrapped, and the arm is driven the short way round to yd.")


def observer_notes(d: Derivation) -> tuple[str, ...]:
    """Lines for the generated headers: W [N m s/rad: p = W theta' is a joint torque, eq. 22], its
    structure and, for w = "auto", the box, rate and certificate it was synthesised for
    (derive.control.certificate.synthesis)."""
    rows = "[" + ", ".join("[" + ", ".join(f"{float(x):.6g}" for x in d.W.row(i)) + "]" for i in range(d.n)) + "]"
    lines = [f"Observer gain W = {rows} {gain_units_text(d.arm.prismatic)} ({d.observer.structure} structure, "
             "eq. 23-25; p = W theta' is a joint torque: the rates W J^-1 are in 1/s)."]
    syn = d.synthesis
    if syn is not None:
        box = ", ".join(f"{x:g}" for x in syn.box)
        lines.append(f"W synthesised (w = 'auto'): smallest ||W||_2 = {syn.norm:.6g} with W + W^T - J' - 2 beta J > 0 "
                     f"for |theta'| <= [{box}] rad/s, beta = {syn.rate:g} 1/s; certificate {syn.decision.verdict.value} "
                     f"({syn.decision.cells} cells).")
    return tuple(lines)


USEFUL = 1e-2   # a relative error above this is not a useful accuracy for a controller


@dataclass(frozen=True)
class SelftestView:
    """Test vectors, their tolerances (per element) and the stated accuracy for the C self-test."""

    rule: str
    accuracy: tuple[tuple[str, str], ...]      # (output, largest norm-wise relative tolerance)
    cases: tuple
    tols: tuple                                # per case: a namespace of tolerance literals per output
    seq: object
    seq_tol: object
    steps: int
    dt: str
    seq_dt: str
    c128: str
    c05: str
    fabs: str
    warnings: tuple[str, ...]


def _namespace(name: str, fields: dict) -> object:
    return type(name, (), fields)


def accuracy_warnings(real: str, acc: dict[str, float], cond: float) -> tuple[str, ...]:
    """A sentence when some output of a ``real`` build cannot be accurate to USEFUL."""
    poor = {k: v for k, v in acc.items() if v > USEFUL}
    if not poor:
        return ()
    worst = max(poor.values())
    names = ", ".join(sorted(poor))
    return (f"--real {real}: expected relative error up to {worst:.2g} ({names}; a derived rounding bound, "
            f"unit roundoff {2.0 ** -53 if real == 'double' else 2.0 ** -24:.2g}): J(theta) has condition number "
            f"up to {cond:.2g} at the test states, and the observer's solve and the laws amplify the rounding "
            f"of {real} by about that much, so a {real} build gives no useful accuracy for this arm"
            + ("; use --real double" if real == "float" else ""),)


def selftest_view(d: Derivation, v: ArmView, count: int = 8) -> SelftestView:
    """Reference vectors (derive.codegen.testvectors) with their derived tolerances,
    as C literals of the view's real type."""
    from derive.codegen import testvectors as tv
    from derive.codegen.balls import to_float
    from derive.codegen.bounds import ApiBounds
    from derive.codegen.reference import Reference

    mode = ParamsMode.RUNTIME if v.runtime else ParamsMode.BAKED
    observer = "implicit" if v.implicit else "explicit"
    ref = Reference(d, observer=observer)
    bounds = ApiBounds(d, v.real, mode, observer=observer)
    lit = lambda xs: tuple(c_literal(x, v.real) for x in xs)  # noqa: E731
    raw = tv.cases(ref, count)
    seq = tv.sequence(ref, bounds)
    tols = tv.case_tolerances(bounds, raw, v.real)
    seq_tols = tv.sequence_tolerances(bounds, seq, v.real)
    acc = tv.accuracy(raw, tols, seq, seq_tols)
    n = d.n
    cond = max(float(np.linalg.cond(np.array([to_float(a) for a in ref.inertia(c.x[:n])]).reshape(n, n)))
               for c in raw)
    cases = tuple(type(c)(*(lit(getattr(c, f)) for f in c.__dataclass_fields__)) for c in raw)
    seq_fields = ("npid_u", "int_e", "dobc_u", "z", "mom_u", "m")
    return SelftestView(
        rule=("element-wise |got - want| <= tol, tol = 2 x the first-order rounding bound of the generated "
              "code at that point (derive.codegen.accuracy) + the rounding of want"
              + (f"; {tv.IMPLICIT_RULE}" if v.implicit else "")),
        accuracy=tuple((name, f"{value:.2g}") for name, value in acc.items()),
        cases=cases, tols=tuple(_namespace("Tol", {f: lit(t[f]) for f in t}) for t in tols),
        seq=_namespace("Seq", {f: lit(getattr(seq, f)) for f in seq_fields}),
        seq_tol=_namespace("SeqTol", {f: lit(t) for f, t in seq_tols.items()}),
        steps=tv.SEQUENCE_STEPS, dt=c_literal(tv.SEQUENCE_DT, v.real), seq_dt=c_literal(seq.dt, v.real), c128=c_literal(128.0, v.real),
        c05=c_literal(0.5, v.real), fabs="fabsf" if v.real == "float" else "fabs",
        warnings=accuracy_warnings(v.real, acc, cond))
