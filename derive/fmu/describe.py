"""Views of a controller FMU: its variables, units and descriptions as plain data.

One :class:`FmuView` serves the C glue (``templates/fmu/*.c.jinja``: which C
lvalue each value reference reads or writes) and the ``modelDescription.xml``
(name, causality, variability, unit, description with the paper's equation).
Built from the arm's view (:func:`derive.codegen.views.arm_view`), the form
registry (:mod:`derive.codegen.forms`) and the arm's parameters, so a change of
the generated API needs an edit here, not in the templates.

Value references: 0 is time (FMI 3), then inputs, outputs, parameters, in the
order of the modelDescription.
"""
from __future__ import annotations

from dataclasses import dataclass
from xml.sax.saxutils import escape

from derive.codegen.forms import Form
from derive.codegen.views import ArmView
from derive.control.pipeline import Derivation
from derive.fmu.units import Unit, fmi_unit

# The controller's inputs (derive.codegen.kernels: theta, dtheta, yd, dyd, ddyd): field, unit, description
INPUTS = (
    ("theta", "rad", "measured angle of joint {i} (eq. 12)"),
    ("dtheta", "rad/s", "measured velocity of joint {i} (eq. 12)"),
    ("yd", "rad", "reference y_d of output {i}, y = C theta (eq. 13, 20)"),
    ("dyd", "rad/s", "first derivative of the reference y_d of output {i} (eq. 20)"),
    ("ddyd", "rad/s^2", "second derivative of the reference y_d of output {i} (eq. 15)"),
)


def xml_text(text: str) -> str:
    """``text`` safe inside an XML attribute value in double quotes."""
    return escape(text, {'"': "&quot;"})


@dataclass(frozen=True)
class Variable:
    """One scalar FMI variable and how the glue reaches it."""

    vr: int
    name: str
    type: str          # FMI 3 type: Float64, Float32 (FMI 2: Real)
    causality: str     # input, output, parameter, local
    variability: str   # continuous, discrete, tunable, constant
    initial: str       # exact, or "" (none)
    start: str         # XML literal, "" for none
    unit: str          # FMI unit name, "" for none
    description: str   # XML-escaped
    get: str           # C rvalue of the instance m (m->in.theta[0]) or a literal
    set: str           # C lvalue, "" when the variable cannot be set
    finite: bool       # the setter refuses a non-finite value (parameters)


@dataclass(frozen=True)
class FmuView:
    """Everything the FMU templates show (plain data)."""

    fmi: int
    arm: str
    ARM: str
    n: int
    real: str            # C real type
    real_type: str       # FMI 3 type of the real variables
    runtime: bool
    model: str           # modelIdentifier
    model_name: str
    description: str     # XML-escaped
    token: str           # instantiationToken (FMI 3) / guid (FMI 2)
    form: Form
    variables: tuple[Variable, ...]
    outputs: tuple[tuple[int, int], ...]   # (value reference, 1-based index in ModelVariables)
    units: tuple[Unit, ...]
    errors: tuple[tuple[str, str], ...]   # (error macro, what it means)
    start_time: str
    stop_time: str
    step_size: str
    tool: str
    sources: tuple[str, ...]    # C files of sources/, compiled together


def errors(v: ArmView) -> tuple[tuple[str, str], ...]:
    """The generated API's error codes (derive.codegen: arm.h) and their meaning."""
    return ((f"{v.ARM}_ENONFINITE", "a non-finite input, state or result"),
            (f"{v.ARM}_EDT", "a sample time that is not finite and > 0"))


def fmu_view(d: Derivation, v: ArmView, f: Form, fmi: int, *, token: str, tool: str, sample_time: float,
             duration: float, sources: tuple[str, ...]) -> FmuView:
    """The view of the controller FMU of form ``f`` (FMI ``fmi``) of arm view ``v``."""
    found, units = variables(d, v, f, fmi)
    outputs = tuple((x.vr, k + 1) for k, x in enumerate(found) if x.causality == "output")
    units = tuple(sorted({*units, fmi_unit("s")}, key=lambda u: u.name)) if fmi == 3 else units
    model = f"{v.arm}_{f.name}"
    return FmuView(
        fmi=fmi, arm=v.arm, ARM=v.ARM, n=v.n, real=v.real,
        real_type="Float32" if v.real == "float" else "Float64", runtime=v.runtime, model=model,
        model_name=model, description=xml_text(f"{f.title}, {f.law} ({f.equations}), of arm {v.arm}: "
                                               f"{v.description}"),
        token=token, form=f, variables=found, outputs=outputs, units=units, errors=errors(v),
        start_time="0.0", stop_time=repr(float(duration)), step_size=repr(float(sample_time)), tool=tool,
        sources=sources)


def _start(value: float) -> str:
    return repr(float(value))


def variables(d: Derivation, v: ArmView, f: Form, fmi: int) -> tuple[tuple[Variable, ...], tuple[Unit, ...]]:
    """The FMU's variables in value-reference order (see the module docstring)
    and the distinct units they use, sorted by name. Real variables are FMI 3
    Float64 or Float32 as the C real type, FMI 2 Real (double) either way."""
    rtype = "Real" if fmi == 2 else "Float32" if v.real == "float" else "Float64"
    known = {str(p.symbol): p for p in d.arm.parameters}
    out: list[Variable] = []
    units: dict[str, Unit] = {}

    def add(name, causality, variability, initial, start, unit, doc, get, set_="", finite=False):
        u = fmi_unit(unit)
        if u is not None:
            units[u.name] = u
        out.append(Variable(len(out) + 1, name, rtype, causality, variability, initial, start,
                            u.name if u else "", xml_text(doc), get, set_, finite))

    for field, unit, doc in INPUTS:
        for i in range(d.n):
            slot = f"m->in.{field}[{i}]"
            add(f"{field}[{i + 1}]", "input", "continuous", "", "0.0", unit, doc.format(i=i + 1), slot, slot)
    law = f"{f.law} ({f.equations})"
    for i in range(d.n):
        add(f"u[{i + 1}]", "output", "discrete", "exact", "0.0", "V",
            f"voltage of motor {i + 1}: {law}, computed from the inputs at the start of the last "
            "communication step and held over it; 0 before the first step", f"m->u[{i}]")
    if f.estimate:
        for i in range(d.n):
            add(f"dhat[{i + 1}]", "output", "discrete", "exact", "0.0", "V",
                f"disturbance estimate of joint {i + 1}, dhat = B^-1 (z + W theta') (eq. 22), "
                "the one the last step used; 0 before the first step", f"m->dhat[{i}]")
    values = {str(s): float(x) for s, x in d.values}
    causality, variability = ("parameter", "tunable") if v.runtime else ("local", "constant")
    for name, literal, doc in v.params:
        p = known.get(name)
        text = f"{p.doc}, from {p.field}" if p is not None else doc
        slot = f"m->params.{name}"
        add(name, causality, variability, "exact", repr(values[name]), p.unit if p is not None else "",
            text, slot if v.runtime else literal, slot if v.runtime else "", finite=True)
    for i, (literal, number) in enumerate(zip(v.u_max, v.py_u_max)):
        slot = f"m->params.u_max[{i}]"
        add(f"u_max[{i + 1}]", causality, variability, "exact", repr(float(number)), "V",
            f"voltage limit of motor {i + 1} (0 = none): u is clipped, the integrator held and the "
            "observer fed the clipped u", slot if v.runtime else literal, slot if v.runtime else "", finite=True)
    return tuple(out), tuple(units[k] for k in sorted(units))
