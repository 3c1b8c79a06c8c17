"""Properties of the arm-file schema, on random arms (hypothesis).

* every valid arm (n = 1..3, positive physical values in sane ranges) loads and
  derives, with J(theta) symmetric positive definite at a sampled angle;
* a valid arm with one field made bad (wrong type, non-finite, out of range,
  an unknown key, a missing key) always ends in a SpecError, never in another
  exception, and the error names that field;
* arbitrary nested data never raises anything but SpecError.
"""
from __future__ import annotations

import copy
import math
import re

import numpy as np
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import derive
from derive.errors import SpecError
from derive.model.names import MAX_LENGTH, name_problem
from derive.codegen.kernels import ParamsMode
from derive.codegen.render import render
from derive.codegen.views import arm_view
from derive.control.ranges import check_ranges
from derive.model.spec import arm_from_dict

from .hypothesis_profiles import PROFILE, examples

# The profile (tests/hypothesis_profiles.py: ci derandomized, fuzz random) gives the rest.
FAST = settings(max_examples=examples(60))
SLOW = settings(max_examples=examples(25))


def between(lo: float, hi: float) -> st.SearchStrategy[float]:
    """Finite floats in [lo, hi], tiny magnitudes (< 1e-100) made 0: a product of such a draw
    and a length could be subnormal, which derive refuses, naming the field (test_ranges.py)."""
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False).map(lambda x: 0.0 if abs(x) < 1e-100 else x)


@st.composite
def valid_arms(draw, n=st.integers(1, 3)) -> dict:
    """A random physically sensible arm mapping (what a TOML file parses to)."""
    n = draw(n)
    links = []
    for _ in range(n):
        length = draw(between(0.05, 1.0))
        link = {"length": length, "mass": draw(between(0.05, 5.0))}
        if draw(st.booleans()):
            link["com"] = draw(between(0.01, 1.0)) * length
        link["inertia"] = draw(st.one_of(st.just("uniform_rod"), between(1e-5, 0.1)))
        if draw(st.booleans()):
            link["viscous_friction"] = draw(between(0.0, 0.1))
        links.append(link)
    motors = []
    for _ in range(n):
        motor = {"torque_constant": draw(between(0.01, 1.0)), "voltage_constant": draw(between(0.0, 1.0)),
                 "resistance": draw(between(0.5, 10.0))}
        motor.update(draw(st.fixed_dictionaries({}, optional={
            "gear_ratio": between(1.0, 50.0), "rotor_inertia": between(0.0, 1e-4),
            "voltage_limit": between(5.0, 48.0)})))
        motors.append(motor)
    point_masses = [{"link": k, "distance": draw(between(0.0, 1.0)) * links[k - 1]["length"],
                     "mass": draw(between(0.01, 1.0)), "inertia": draw(between(0.0, 1e-3)),
                     "label": draw(st.sampled_from(["tip", "motor", ""]))}
                    for k in draw(st.lists(st.integers(1, n), max_size=3))]
    T1 = draw(between(0.0, 1.0))
    w = sorted(draw(st.lists(between(0.1, 20.0), min_size=n, max_size=n)))
    controller = {"T1": T1, "T2": T1 + draw(between(0.05, 2.0)), "w": w}
    if draw(st.booleans()):  # lower triangular with a nonzero diagonal: invertible
        controller["C"] = [[draw(st.sampled_from([0.5, 1.0, 2.0])) if i == j else
                            (draw(between(-1.0, 1.0)) if j < i else 0.0) for j in range(n)] for i in range(n)]
    if draw(st.booleans()):
        controller["max_joint_speed"] = draw(st.lists(between(0.1, 50.0), min_size=n, max_size=n))
    return {"arm": {"name": draw(st.sampled_from(["my_arm", "arm2", "robot_a"])),
                    "description": "random arm", "gravity": draw(st.sampled_from([0.0, 9.81]))},
            "link": links, "point_mass": point_masses, "motor": motors, "controller": controller}


@SLOW
@given(valid_arms(), st.lists(between(-math.pi, math.pi), min_size=3, max_size=3))
def test_valid_arms_load_and_derive_with_J_symmetric_positive_definite(data, angles):
    arm = arm_from_dict(data)
    d = derive.derive(arm)
    point = {t: sp.Float(a, 30) for t, a in zip(d.theta, angles)}
    J = np.array(d.J.xreplace(point).evalf(30).tolist(), dtype=float)
    assert J.shape == (arm.n, arm.n)
    np.testing.assert_allclose(J, J.T, rtol=1e-12, atol=0, err_msg="J(theta) not symmetric")
    assert np.linalg.eigvalsh(J).min() > 0, f"J(theta) not positive definite at {angles}: {J}"


# -- one field made bad ---------------------------------------------------------------

WRONG_TYPE = st.one_of(
    st.text(max_size=12).filter(lambda s: "/" not in s and s != "uniform_rod"),
    st.booleans(), st.none(), st.lists(st.integers(), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2))
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf, 10 ** 400, -(10 ** 400), "1/0", "1/1e999"])
NEGATIVE = st.one_of(st.floats(-1e6, -1e-9), st.integers(-10 ** 6, -1))
NOT_POSITIVE = st.one_of(NEGATIVE, st.sampled_from([0, 0.0, -0.0, "0/1"]))

# leaf paths by what they accept; %d is a 1-based row, filled from the arm
POSITIVE = ["link/%d/length", "link/%d/mass", "motor/%d/torque_constant", "motor/%d/resistance",
            "motor/%d/gear_ratio", "point_mass/%d/mass", "controller/T2"]
NONNEGATIVE = ["link/%d/inertia", "link/%d/viscous_friction", "motor/%d/voltage_constant",
               "motor/%d/rotor_inertia", "point_mass/%d/inertia", "controller/T1", "arm/gravity"]
FINITE = ["link/%d/com", "point_mass/%d/distance"]


def _parts(path: str, data: dict, row: int) -> list:
    parts = []
    for p in path.split("/"):
        if p == "%d":
            rows = data[parts[-1]]
            parts.append((row % len(rows)) if rows else None)
        else:
            parts.append(p)
    return parts


def _set(data: dict, parts: list, value) -> str | None:
    """Put value at parts; the field name the error must carry, or None if the path is absent."""
    if None in parts:
        return None
    target = data
    for p in parts[:-1]:
        target = target[p]
    target[parts[-1]] = value
    field = parts[0]
    for p in parts[1:]:
        field += f"[{p + 1}]" if isinstance(p, int) else f".{p}"
    return field


@st.composite
def one_bad_field(draw) -> tuple[dict, str | None]:
    data = copy.deepcopy(draw(valid_arms()))
    row = draw(st.integers(0, 5))
    kind = draw(st.sampled_from(["positive", "nonnegative", "finite", "name", "array", "unknown", "missing"]))
    if kind in ("positive", "nonnegative", "finite"):
        paths, bad = {"positive": (POSITIVE, st.one_of(WRONG_TYPE, NON_FINITE, NOT_POSITIVE)),
                      "nonnegative": (NONNEGATIVE, st.one_of(WRONG_TYPE, NON_FINITE, NEGATIVE)),
                      "finite": (FINITE, st.one_of(WRONG_TYPE, NON_FINITE))}[kind]
        field = _set(data, _parts(draw(st.sampled_from(paths)), data, row), draw(bad))
        if field is None:  # no point mass to spoil: spoil the name instead
            data["arm"]["name"], field = "int", "arm.name"
        return data, field
    if kind == "name":
        data["arm"]["name"] = draw(st.one_of(WRONG_TYPE.filter(lambda v: not isinstance(v, str)),
                                             st.text(min_size=1).filter(lambda s: name_problem(s) is not None)))
        return data, "arm.name"
    if kind == "array":
        key = draw(st.sampled_from(["w", "max_joint_speed", "C"]))
        n = len(data["link"])
        data["controller"][key] = draw(st.one_of(
            st.lists(st.floats(0.1, 10.0), max_size=5).filter(lambda v: len(v) != n), WRONG_TYPE, NON_FINITE))
        return data, f"controller.{key}"
    table = draw(st.sampled_from(["", "arm", "link", "motor", "controller"]))
    target = data if table == "" else data[table][0] if isinstance(data[table], list) else data[table]
    if kind == "unknown":
        key = draw(st.text(min_size=1, max_size=8).filter(lambda k: k not in target))
        target[key] = draw(st.one_of(st.integers(), st.text(max_size=5), st.floats()))
        return data, None  # the field is the key, shown escaped: checked by the count only
    required = {"": ["arm", "link", "motor", "controller"], "arm": ["name"], "link": ["length", "mass"],
                "motor": ["torque_constant", "voltage_constant", "resistance"],
                "controller": ["T1", "T2", "w"]}[table]
    key = draw(st.sampled_from(required))
    del target[key]
    return data, (f"{table}[1].{key}" if table in ("link", "motor") else f"{table}.{key}" if table else key)


@FAST
@given(one_bad_field())
def test_one_bad_field_is_a_spec_error_naming_it(case):
    data, field = case
    try:
        arm_from_dict(data)
    except SpecError as exc:
        fields = [p.field for p in exc.problems]
        assert exc.problems and all(p.expected and p.given for p in exc.problems)
        if field is not None:
            assert any(f == field or f.startswith(field + "[") for f in fields), (field, str(exc))
    else:
        raise AssertionError(f"accepted a bad arm: {data}")


@st.composite
def extreme_arms(draw) -> dict:
    """A valid arm mapping whose values span the whole double range (1e-300 .. 1e300)."""
    data = draw(valid_arms(n=st.integers(1, 2)))
    scale = lambda: 10.0 ** draw(st.integers(-300, 300))  # noqa: E731
    key = draw(st.sampled_from(["length", "mass", "inertia", "T2", "w", "torque_constant", "rotor_inertia"]))
    factor = scale()
    for link in data["link"]:
        if key in ("length", "mass") or (key == "inertia" and link["inertia"] != "uniform_rod"):
            link[key] = link[key] * factor
            link.pop("com", None)  # com scales with the length by default
    for motor in data["motor"]:
        if key in ("torque_constant", "rotor_inertia"):
            motor[key] = motor.get(key, 1e-5) * factor
    for pm in data["point_mass"]:
        pm["distance"] = min(pm["distance"], min(link["length"] for link in data["link"]))
    ctl = data["controller"]
    if key == "T2":
        ctl["T1"], ctl["T2"] = 0.0, factor
    if key == "w":
        ctl["w"] = [w * factor for w in ctl["w"]]
    return data


@settings(max_examples=examples(15))
@given(extreme_arms())
def test_extreme_values_give_normal_kernel_constants_or_a_spec_error_naming_fields(data):
    """Issue 10, item 2: a derived constant beyond a real type's range never reaches the
    kernels; every arm either prints them (every literal finite) or is refused naming fields.
    (The self-test vectors, computed from the model at sampled states, are not drawn here.)"""
    try:
        arm = arm_from_dict(data)
    except SpecError:
        return  # e.g. a product of the scale with a drawn value that is not a finite double
    try:
        d = derive.derive(arm)
    except SpecError as exc:
        assert all(p.field.split("[")[0].split(".")[0] in ("link", "point_mass", "motor", "controller", "arm")
                   for p in exc.problems), str(exc)
        return
    for real in ("double", "float"):
        try:
            check_ranges(d, real)
        except SpecError as exc:
            assert real == "float" and "float" in str(exc), str(exc)
            continue
        view = arm_view(d, real, ParamsMode.BAKED)  # the printer raises on any constant out of range
        kernels = render("c/kernels.c.jinja", v=view)
        assert not re.search(r"\b(inf|nan|INFINITY|NAN)\b", kernels)


JSONISH = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=8)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=20)


@FAST
@given(st.one_of(JSONISH, st.dictionaries(st.sampled_from(["arm", "link", "point_mass", "motor", "controller"]),
                                           JSONISH, max_size=5)))
def test_arbitrary_data_is_a_spec_error_never_another_exception(data):
    try:
        arm_from_dict(data)
    except SpecError as exc:
        assert "\n  - " in str(exc)


@FAST
@given(st.text(max_size=40))
def test_accepted_names_are_lowercase_c_identifiers(text):
    why = name_problem(text)
    if why is None:
        assert text.isascii() and text.isidentifier() and text == text.lower() and len(text) <= MAX_LENGTH
    else:
        assert why.endswith(repr(text)) or "characters)" in why


def test_the_default_profile_draws_the_same_examples_on_every_run():
    """make test and CI: derandomized, no example database (issue 10, item 1);
    make fuzz: a new seed each run, many more examples."""
    current = settings.default
    assert current.database is None and current.deadline is None
    assert current.derandomize == (PROFILE == "ci")
    assert FAST.max_examples == (60 if PROFILE == "ci" else 60 * examples(1)) and examples(1) >= 1
