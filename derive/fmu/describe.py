"""Views of the FMUs: variables, units and descriptions as plain data.

:class:`FmuView` (a controller form) and :class:`PlantView` (the simulation
plant, derive.fmu.plant) share the fields the FMI shells and the XML templates
read (``templates/fmu/fmi{2,3}.c.jinja``, ``modelDescription{2,3}.xml.jinja``);
each names its core template (``x.core``). A view serves the C glue (which C
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

import sympy as sp

from derive.codegen.forms import Form, init_takes_dt
from derive.codegen.views import ArmView
from derive.control.pipeline import Derivation
from derive.fmu.rules import RulesView, fmu_rules, single_checks
from derive.fmu.units import Unit, fmi_unit
from derive.model.actuators import input_word
from derive.model.chain import Parameter
from derive.model.rules import domain_rules
from derive.model.spec import T1_SYMBOL, T2_SYMBOL

# The controller's inputs (derive.codegen.kernels: theta, dtheta, yd, dyd, ddyd): field, unit, description
INPUTS = (
    ("theta", "rad", "measured angle of joint {i} (eq. 12)"),
    ("dtheta", "rad/s", "measured velocity of joint {i} (eq. 12)"),
    ("yd", "rad", "reference y_d of output {i}, y = C theta (eq. 13, 20)"),
    ("dyd", "rad/s", "first derivative of the reference y_d of output {i} (eq. 20)"),
    ("ddyd", "rad/s^2", "second derivative of the reference y_d of output {i} (eq. 15)"),
)


U_MAX = sp.Symbol("u_max", nonnegative=True)   # an FMU's input limit: >= 0, 0 = none


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
    check: str = ""    # C condition on ``value`` the setter demands (a parameter's own range), "" none
    minimum: str = ""  # XML min (the same range), "" none
    range: str = ""    # the range in words ("> 0"), for the setter's message


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
    initial_unknowns: tuple[tuple[int, int], ...]   # none: the outputs start at 0
    mask: str            # C type of the API's clipped-joints mask, "" when it has none
    units: tuple[Unit, ...]
    errors: tuple[tuple[str, str], ...]   # (error macro, what it means)
    ok: str              # the API's success code
    includes: tuple[str, ...]   # headers the glue includes
    core: str            # the template of the FMU's core (instance, variables, step)
    summary: str
    start_time: str
    stop_time: str
    step_size: str
    tool: str
    sources: tuple[str, ...]    # C files of sources/, compiled together
    init_dt: bool = False       # the form's init takes dt (the implicit DOBC: derive.codegen.forms.init_takes_dt)
    estimate_after: bool = False   # the estimate a step applied is read after it (the implicit DOBC moves z first)
    rules: RulesView | None = None   # the arm file's rules on several tunable parameters (derive.fmu.rules)


def mask_type(v: ArmView) -> str:
    """The C type of the API's clipped-joints mask (``<arm>_mask``, issue 15 item 4),
    "" while the generated API has none: the glue passes it to every step and the
    FMU shows it as Boolean outputs ``clipped[i]`` only when it exists."""
    return f"{v.arm}_mask" if getattr(v, "mask", "") else ""


def errors(v: ArmView) -> tuple[tuple[str, str], ...]:
    """The generated API's error codes (derive.codegen: arm.h) and their meaning."""
    return ((f"{v.ARM}_ENONFINITE", "a non-finite input, state or result"),
            (f"{v.ARM}_EDT", "a sample time that is not finite and > 0"))


def fmu_view(d: Derivation, v: ArmView, f: Form, fmi: int, *, token: str, tool: str, sample_time: float,
             duration: float, sources: tuple[str, ...]) -> FmuView:
    """The view of the controller FMU of form ``f`` (FMI ``fmi``) of arm view ``v``."""
    found, units, rules = variables(d, v, f, fmi)
    outputs = tuple((x.vr, k + 1) for k, x in enumerate(found) if x.causality == "output")
    units = tuple(sorted({*units, fmi_unit("s")}, key=lambda u: u.name)) if fmi == 3 else units
    model = f"{v.arm}_{f.name}"
    step = " with the implicit (backward-Euler) observer step" if v.implicit else ""
    return FmuView(
        fmi=fmi, arm=v.arm, ARM=v.ARM, n=v.n, real=v.real,
        real_type="Float32" if v.real == "float" else "Float64", runtime=v.runtime, model=model,
        model_name=model, description=xml_text(f"{f.title}, {f.law} ({f.equations}){step}, of arm {v.arm}: "
                                               f"{v.description}"),
        token=token, form=f, variables=found, outputs=outputs, initial_unknowns=(), mask=mask_type(v),
        units=units, errors=errors(v),
        ok=f"{v.ARM}_OK", includes=(f"{v.arm}.h",), core="fmu/controller.c.jinja",
        summary=f"{f.title} of arm {v.arm}, {f.law} ({f.equations}){step}",
        start_time="0.0", stop_time=repr(float(duration)), step_size=repr(float(sample_time)), tool=tool,
        sources=sources, init_dt=init_takes_dt(f, "implicit" if v.implicit else "explicit"),
        estimate_after=v.implicit and f.name == "dobc", rules=rules)


def _start(value: float) -> str:
    return repr(float(value))


def variables(d: Derivation, v: ArmView, f: Form, fmi: int
              ) -> tuple[tuple[Variable, ...], tuple[Unit, ...], RulesView | None]:
    """The FMU's variables in value-reference order (see the module docstring),
    the distinct units they use, sorted by name, and the rules on several tunable parameters
    (runtime parameters: derive.fmu.rules; each parameter's own range is its setter's). Real
    variables are FMI 3 Float64 or Float32 as the C real type, FMI 2 Real (double) either way."""
    rtype = "Real" if fmi == 2 else "Float32" if v.real == "float" else "Float64"
    arm = d.arm
    known = {str(p.symbol): p for p in arm.parameters}
    every = arm.parameters + tuple(Parameter(s, x, "", "", "") for s, x in d.values if str(s) not in known)
    single, rules = fmu_rules(every, {name: f"m->params.{name}" for name, _, _ in v.params}, v.real,
                              horizon_symbols=(T1_SYMBOL, T2_SYMBOL), W=d.observer.W,
                              bodies=arm.spatial.bodies if arm.spatial is not None else ()) if v.runtime else ({}, None)
    single["u_max"] = single_checks(domain_rules((Parameter(U_MAX, 0, "", "", ""),)))["u_max"]
    out: list[Variable] = []
    units: dict[str, Unit] = {}

    def add(name, causality, variability, initial, start, unit, doc, get, set_="", finite=False, kind=None,
            rule=""):
        u = fmi_unit(unit)
        if u is not None:
            units[u.name] = u
        check, minimum, words = single[rule] if rule in single and set_ else ("", "", "")
        words = f"{words} {u.name}" if words and u is not None else words
        out.append(Variable(len(out) + 1, name, kind or rtype, causality, variability, initial, start,
                            u.name if u else "", xml_text(doc), get, set_, finite, check, minimum, words))

    for field, unit, doc in INPUTS:
        for i in range(d.n):
            slot = f"m->in.{field}[{i}]"
            add(f"{field}[{i + 1}]", "input", "continuous", "", "0.0", unit, doc.format(i=i + 1), slot, slot)
    law = f"{f.law} ({f.equations})"
    units_u = d.arm.input_units   # V, or N m (N) in torque mode, per motor
    what = {"V": "voltage", "N m": "torque", "N": "force"}
    for i in range(d.n):
        add(f"u[{i + 1}]", "output", "discrete", "exact", "0.0", units_u[i],
            f"{what[units_u[i]]} of motor {i + 1}: {law}, computed from the inputs at the start of the last "
            "communication step and held over it; 0 before the first step", f"m->u[{i}]")
    if f.estimate:
        for i in range(d.n):
            add(f"dhat[{i + 1}]", "output", "discrete", "exact", "0.0", units_u[i],
                f"disturbance estimate of joint {i + 1}, {f.estimate_law}, "
                "the one the last step used; 0 before the first step", f"m->dhat[{i}]")
    if mask_type(v):
        for i in range(d.n):
            add(f"clipped[{i + 1}]", "output", "discrete", "exact", "false", "",
                f"true when the last step clipped the {what[units_u[i]]} of motor {i + 1} to u_max[{i + 1}] (the API's "
                "mask; the integrator held, the observer fed the clipped u); false before the first step",
                f"((m->clipped >> {i}) & 1u)", kind="Boolean")
    values = {str(s): float(x) for s, x in d.values}
    causality, variability = ("parameter", "tunable") if v.runtime else ("local", "constant")
    for name, literal, doc in v.params:
        p = known.get(name)
        text = f"{p.doc}, from {p.field}" if p is not None else doc
        slot = f"m->params.{name}"
        add(name, causality, variability, "exact", repr(values[name]), p.unit if p is not None else "",
            text, slot if v.runtime else literal, slot if v.runtime else "", finite=True, rule=name)
    for i, (literal, number) in enumerate(zip(v.u_max, v.py_u_max)):
        slot = f"m->params.u_max[{i}]"
        add(f"u_max[{i + 1}]", causality, variability, "exact", repr(float(number)), units_u[i],
            f"{what[units_u[i]]} limit of motor {i + 1} (0 = none): u is clipped, the integrator held and the "
            "observer fed the clipped u", slot if v.runtime else literal, slot if v.runtime else "", finite=True,
            rule="u_max")
    return tuple(out), tuple(units[k] for k in sorted(units)), rules


@dataclass(frozen=True)
class PlantView:
    """Everything the plant FMU's templates show (plain data); the shell fields
    (fmi .. summary) are those of :class:`FmuView`."""

    fmi: int
    model: str
    model_name: str
    description: str
    token: str
    tool: str
    units: tuple[Unit, ...]
    variables: tuple[Variable, ...]
    outputs: tuple[tuple[int, int], ...]
    initial_unknowns: tuple[tuple[int, int], ...]
    start_time: str
    stop_time: str
    step_size: str
    sources: tuple[str, ...]
    errors: tuple[tuple[str, str], ...]
    ok: str
    includes: tuple[str, ...]
    core: str
    summary: str
    real_type: str
    n: int
    np: int
    kernels: tuple
    defaults: tuple[tuple[str, str], ...]   # (C lvalue, C literal) set at instantiation and reset
    substeps: int
    rules: RulesView | None = None   # the arm file's rules on several of the true arm's parameters


def plant_variables(n: int, params: tuple[tuple[str, float, str, str], ...],
                    vectors: tuple[tuple[str, object, str, tuple[float, ...]], ...],
                    scalars: tuple[tuple[str, str, str, float], ...],
                    fmi: int, inputs: tuple[str, ...] | None = None,
                    single: dict[str, tuple[str, str, str]] | None = None
                    ) -> tuple[tuple[Variable, ...], tuple[Unit, ...], tuple[tuple[str, str], ...]]:
    """The plant FMU's variables: input u, outputs (the controller's inputs), and
    tunable parameters: ``params`` (name, value, unit, description) of the true
    arm (m->p[k]); ``vectors`` (name, unit, description, values) per joint and
    ``scalars`` (name, unit, description, value), each read from the instance
    field of the same name (a vector's unit: one string, or one per joint). ``inputs``: the
    unit of each u_i (V, or N m in torque mode); ``single``: the setter's check of a parameter by
    name (derive.fmu.rules.single_checks). Also the units and the defaults (C lvalue, literal)."""
    from derive.codegen.printing import c_literal

    rtype = "Real" if fmi == 2 else "Float64"
    out: list[Variable] = []
    units: dict[str, Unit] = {}
    defaults: list[tuple[str, str]] = []

    def add(name, causality, variability, initial, start, unit, doc, get, set_="", finite=False):
        u = fmi_unit(unit)
        if u is not None:
            units[u.name] = u
        check, minimum, words = (single or {}).get(name, ("", "", "")) if set_ else ("", "", "")
        words = f"{words} {u.name}" if words and u is not None else words
        out.append(Variable(len(out) + 1, name, rtype, causality, variability, initial, start,
                            u.name if u else "", xml_text(doc), get, set_, finite, check, minimum, words))

    inputs = inputs or ("V",) * n
    what = {"V": "voltage", "N m": "torque", "N": "force"}
    for i in range(n):
        add(f"u[{i + 1}]", "input", "continuous", "", "0.0", inputs[i],
            f"{what[inputs[i]]} of motor {i + 1}, held over the communication step (zero-order hold)", f"m->u[{i}]",
            f"m->u[{i}]")
    for field, unit, doc in INPUTS:
        for i in range(n):
            k = i if field in ("theta", "yd") else n + i
            slot = {"theta": f"m->x[{k}]", "dtheta": f"m->x[{k}]", "yd": f"m->f[{k}]", "dyd": f"m->f[{k}]",
                    "ddyd": f"m->ddyd[{i}]"}[field]
            text = doc.format(i=i + 1).replace("measured", "true")
            add(f"{field}[{i + 1}]", "output", "continuous", "calculated", "", unit, text, slot)
    for k, (name, value, unit, doc) in enumerate(params):
        slot = f"m->p[{k}]"
        add(name, "parameter", "tunable", "exact", repr(value), unit, doc, slot, slot, finite=True)
        defaults.append((slot, c_literal(value, "double")))
    for name, unit, doc, values in vectors:
        field = name.split("[")[0]
        for i, value in enumerate(values):
            slot = f"m->{field}[{i}]"
            add(f"{name}[{i + 1}]", "parameter", "tunable", "exact", repr(value),
                unit if isinstance(unit, str) else unit[i], doc.format(i=i + 1), slot, slot, finite=True)
            defaults.append((slot, c_literal(value, "double")))
    for name, unit, doc, value in scalars:
        slot = f"m->{name}"
        add(name, "parameter", "tunable", "exact", repr(value), unit, doc, slot, slot, finite=True)
        defaults.append((slot, c_literal(value, "double")))
    return tuple(out), tuple(units[k] for k in sorted(units)), tuple(defaults)


def plant_view(d, fmi: int, *, token: str, tool: str, sample_time: float, sources: tuple[str, ...]) -> PlantView:
    """The view of the plant FMU of the ``[simulation]`` section of ``d``'s arm (derive.fmu.plant)."""
    from derive.fmu.plant import payload_shape_words, plant_kernels, plant_parameters
    from derive.model.simspec import coulomb_widths, pulse_amplitudes
    from derive.sim.plant import payload_com
    from derive.sim.start import reference_offset

    arm = d.arm
    s = arm.simulation
    values, plant = plant_parameters(d, s)
    known = {str(p.symbol): p for p in arm.parameters}
    params = []
    for sym, value in values:
        p = known.get(str(sym))
        what = f"{p.doc} (from {p.field})" if p is not None else str(sym)
        mismatch = plant.changed.get(str(sym))
        note = (f"; the arm file's {mismatch[0]!r} with the [simulation] mismatch applied" if mismatch is not None
                else "")
        params.append((str(sym), value, p.unit if p is not None else "", f"{what} of the simulated arm{note}"))
    limits = tuple(float(m.input_limit) if m.input_limit else 0.0 for m in arm.motors)
    forces = tuple("N" if p else "N m" for p in arm.prismatic)
    word = input_word(arm.input_units)
    limit_field = {"voltage": "motor.voltage_limit", "torque": "motor.torque_limit"}.get(
        word, "motor.voltage_limit or motor.torque_limit")
    vectors = (
        ("coulomb", forces, "Coulomb friction tau_c of joint {i}, tau_c tanh(theta'/eps) (simulation.coulomb_friction)",
         s.coulomb_friction),
        ("coulomb_smoothing", tuple("m/s" if p else "rad/s" for p in arm.prismatic),
         "the width eps > 0 of joint {i}'s smooth Coulomb law tau_c tanh(theta'/eps) (simulation.coulomb_smoothing)",
         coulomb_widths(s, arm.n)),
        ("viscous", tuple("N s/m" if p else "N m s/rad" for p in arm.prismatic),
         "extra viscous friction of joint {i} (simulation.viscous_friction)", s.viscous_friction),
        ("dist", arm.input_units, "constant input disturbance d of motor {i}, B (u + d) (eq. 12; simulation.disturbance)",
         s.disturbance),
        ("u_max", arm.input_units, f"the amplifier's {word} limit of motor {{i}}, 0 = none ({limit_field})", limits),
        ("start", "s", "when the pulse train of link {i} starts (simulation.start)", s.start),
        ("theta0", "rad", "angle of joint {i} at the start, at rest (simulation.initial_theta)", s.initial_theta),
        ("amplitude", tuple("m" if p else "rad" for p in arm.prismatic),
         "pulse amplitude of joint {i} (simulation.amplitude, or amplitude_deg; section 5.2)", pulse_amplitudes(s, arm.n)),
        ("yd0", "rad", "y_d(0) of output {i}: the reference starts there at rest and the pulse train is added to "
         "it; 0, or C theta0 for simulation.reference_start = \"measured\" (set it with theta0)",
         tuple(float(v) for v in reference_offset(d, s))),
    )
    vectors += (("payload_com", "m", "component {i} (x, y, z) of the payload's centre of mass in the tip link's "
                 "frame (simulation.payload_com)", payload_com(d, s)),)
    scalars = (("period", "s", "period of the pulse train (simulation.pulse_period, section 5.2)", s.pulse_period),
               ("payload_mass", "kg", "mass of a rigid payload on the tip, J + J_p, G + G_p (eq. 12; "
                "simulation.payload_mass; its inertia: " + payload_shape_words(d) + ")", s.payload_mass))
    every = tuple(known.get(str(sym)) or Parameter(sym, value, "", "", "") for sym, value in values)
    single, rules = fmu_rules(every, {str(sym): f"m->p[{k}]" for k, (sym, _) in enumerate(values)}, "double",
                              bodies=arm.spatial.bodies if arm.spatial is not None else ())
    single["payload_mass"] = ("value >= 0", "0.0", ">= 0")
    single.update({f"coulomb_smoothing[{i + 1}]": ("value > 0", "0.0", "> 0") for i in range(arm.n)})
    found, units, defaults = plant_variables(arm.n, tuple(params), vectors, scalars, fmi, arm.input_units, single)
    if fmi == 3:
        units = tuple(sorted({*units, fmi_unit("s")}, key=lambda u: u.name))
    listed = tuple((x.vr, k + 1) for k, x in enumerate(found) if x.causality == "output")
    model = f"{arm.name}_plant"
    return PlantView(
        fmi=fmi, model=model, model_name=model,
        description=xml_text(f"simulation plant of arm {arm.name} ([simulation] of its arm file): the true arm "
                             f"with friction, heavier tip, payload, input disturbance and {input_word(arm.input_units)} limits "
                             "(eq. 12), and the "
                             "reference Gr(s) = 1/(s^2 + 1.8 s + 1) of a pulse train (section 5.2); RK4 with "
                             f"{s.substeps} substeps per communication step"),
        token=token, tool=tool, units=units, variables=found, outputs=listed, initial_unknowns=listed,
        start_time="0.0", stop_time=repr(float(s.duration)), step_size=repr(float(sample_time)), sources=sources,
        errors=(("PLANT_ENONFINITE", "a non-finite input u or plant state"),), ok="PLANT_OK", includes=(),
        core="fmu/plant.c.jinja",
        summary=f"simulation plant of arm {arm.name}: RK4, {s.substeps} substeps per step, u held",
        real_type="Float64", n=arm.n, np=len(values), kernels=plant_kernels(d, tuple(v[0] for v in values),
                                                                            s.substeps),
        defaults=defaults, substeps=s.substeps, rules=rules)
