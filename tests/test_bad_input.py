"""Bad arm files: every malformed or impossible input gets ONE SpecError that
names each problem's field, expected and given value; the CLI turns it into one
message on stderr and exit code 2, with no traceback and nothing written.

One table, ``CASES``: an id, a way to corrupt a valid arm (the default arm's
TOML text, or ``tests/arms.py: chain_dict``), the fields the message must name
and a fragment of the expected or given text. Rows marked ``cli`` also run
through ``python -m derive show FILE`` (about 1 s each, so only a subset).
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

import derive
from derive.errors import DeriveError, SpecError
from derive.model.names import name_problem
from derive.model.spec import ARMS_DIR, arm_from_dict

from .arms import chain_dict

DEFAULT_TEXT = (ARMS_DIR / "glasgow_2link.toml").read_text(encoding="utf-8")
ROOT = Path(__file__).resolve().parent.parent


# -- writing arm files --------------------------------------------------------------------

def toml_value(v) -> str:
    """A value as TOML source (enough for arm files: no dates, no nested tables of tables)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, (int, str)):
        return json.dumps(v) if isinstance(v, str) else str(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"


def toml_key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def to_toml(data: dict) -> str:
    """An arm mapping as a TOML document: [table] and [[array of tables]] sections."""
    out = []
    for key, value in data.items():
        blocks = value if isinstance(value, list) and value and all(isinstance(x, dict) for x in value) else None
        if isinstance(value, dict):
            blocks = [value]
        if blocks is None:
            out.insert(0, f"{toml_key(key)} = {toml_value(value)}")
            continue
        for block in blocks:
            out.append(f"\n[{toml_key(key)}]" if isinstance(value, dict) else f"\n[[{toml_key(key)}]]")
            out += [f"{toml_key(k)} = {toml_value(v)}" for k, v in block.items()]
    return "\n".join(out) + "\n"


# -- ways to corrupt a valid arm ----------------------------------------------------------

Make = Callable[[], "str | bytes | None"]


def edit(old: str, new: str) -> Make:
    """The default arm's text with the first ``old`` replaced by ``new``."""
    def make() -> str:
        assert old in DEFAULT_TEXT, f"corruption out of date: {old!r} not in the default arm"
        return DEFAULT_TEXT.replace(old, new, 1)
    return make


def append(text: str) -> Make:
    return lambda: DEFAULT_TEXT + text


def prepend(text: str) -> Make:
    """Text before the first table: top-level keys."""
    return lambda: text + DEFAULT_TEXT


def chain(change: Callable[[dict], object], n: int = 2) -> Make:
    """tests/arms.py chain_dict(n), changed in place by ``change``, as TOML."""
    def make() -> str:
        data = chain_dict(n)
        change(data)
        return to_toml(data)
    return make


def name(value) -> Make:
    """The default arm with arm.name set to ``value`` (any TOML value)."""
    return edit('name = "glasgow_2link"', f"name = {toml_value(value)}")


def name_text(source: str) -> Make:
    """The default arm with arm.name written as the raw TOML ``source``."""
    return edit('name = "glasgow_2link"', f"name = {source}")


def pop(*path):
    def change(d):
        for p in path[:-1]:
            d = d[p]
        del d[path[-1]]
    return change


def put(value, *path):
    def change(d):
        for p in path[:-1]:
            d = d[p]
        d[path[-1]] = value
    return change


def both(*changes):
    def change(d):
        for c in changes:
            c(d)
    return change


M1 = "mass = 0.361             # kg (appendix: link masses 0.361 kg)"
L1 = "length = 0.38            # m (appendix: first and second link lengths 0.38 m)"
KT1, KV1 = "torque_constant = 0.23   # N m/A (appendix)", "voltage_constant = 0.29  # V s/rad (appendix)"
R1 = "resistance = 3.4         # ohm (appendix)"
W = "w = [1.0, 2.0]"
C = "C = [[1.0, 0.0], [0.0, 1.0]]"
T1, T2 = "T1 = 0.0", 'T2 = "1/1.2"'
DESC = re.search(r"^description = .*$", DEFAULT_TEXT, re.M)[0]


def hollow_tip(d: dict) -> None:
    """Everything on the last link sits on its joint: J is singular for every theta."""
    d["link"][-1].update(com=0.0, inertia=0.0)
    d["point_mass"] = [p for p in d["point_mass"] if p["link"] != len(d["link"])]
    d["motor"][-1]["rotor_inertia"] = 0.0


def massless_tip(d: dict) -> None:
    """The last link massless (mass 0, inertia 0, valid: issue 10 item 7) and carrying
    nothing: then joint 2 moves no inertia at all."""
    d["link"][-1].update(mass=0.0, inertia=0.0)
    d["point_mass"] = [p for p in d["point_mass"] if p["link"] != len(d["link"])]
    d["motor"][-1]["rotor_inertia"] = 0.0


def many_problems() -> str:
    """Seven problems in seven places of one file."""
    text = DEFAULT_TEXT
    for old, new in ((M1, "mass = -0.3\nmasse = 1"), (R1, "resistance = 0"), (W, "w = [2.0, 0.0]"),
                     (T1, "T1 = 5"), ('name = "glasgow_2link"', 'name = "int"'), (C, "C = [[1, 1], [1, 1]]")):
        text = text.replace(old, new, 1)
    return text


@dataclass(frozen=True)
class Case:
    id: str
    make: Make          # the bad file's text (bytes: raw; None: no file at all)
    fields: tuple[str, ...]
    match: str          # a fragment of the message (expected or given), matched literally
    cli: bool = False
    filename: str = "arm.toml"  # "." : the folder itself


C_ = Case
CASES = [
    # structure: unknown keys, missing fields, missing tables
    C_("unknown-top-table", append("\n[extra]\nx = 1\n"), ("extra",), "an unknown key set to table", cli=True),
    C_("unknown-link-key", edit(L1, "lenght = 0.38"), ("link[1].lenght", "link[1].length"), "did you mean 'length'?"),
    C_("capitalised-key", edit(M1, "Mass = 0.361"), ("link[1].Mass", "link[1].mass"), "did you mean 'mass'?"),
    C_("unknown-controller-key", edit(W, W + "\nhorizon = 2.0"), ("controller.horizon",), "unknown key set to 2.0"),
    C_("escape-in-key", prepend('"bad\\u001b[31mkey" = 1\n'), ("'bad\\x1b[31mkey'",), "unknown key"),
    C_("missing-mass", edit(M1, ""), ("link[1].mass",), "the key is missing"),
    C_("missing-name", edit('name = "glasgow_2link"', ""), ("arm.name",), "the key is missing"),
    C_("missing-arm-table", chain(pop("arm")), ("arm",), "a table [arm]"),
    C_("missing-motors", chain(pop("motor")), ("motor",), "one [[motor]] table per joint"),
    C_("missing-controller", chain(pop("controller")), ("controller",), "the key is missing"),
    C_("missing-T2", chain(pop("controller", "T2")), ("controller.T2",), "a finite number > 0 (s)"),
    C_("zero-links", chain(put([], "link")), ("link",), "at least one [[link]]", cli=True),
    C_("link-not-array", chain(put({"length": 0.3, "mass": 0.3}, "link")), ("link",), "an array of tables"),
    C_("motor-count", chain(lambda d: d["motor"].pop()), ("motor",), "got 1 [[motor]] table"),
    C_("motor-extra", chain(lambda d: d["motor"].append(dict(d["motor"][0]))), ("motor",), "got 3 [[motor]] tables"),
    # wrong types
    C_("string-mass", edit(M1, 'mass = "abc"'), ("link[1].mass",), "got string 'abc'", cli=True),
    C_("quoted-number", edit(T2, 'T2 = "0.5"'), ("controller.T2",), "a number in quotes"),
    C_("boolean-resistance", edit(R1, "resistance = true"), ("motor[1].resistance",), "got boolean true"),
    C_("boolean-gravity", edit("gravity = 0.0", "gravity = false"), ("arm.gravity",), "got boolean false"),
    C_("array-mass", edit(M1, "mass = [0.361]"), ("link[1].mass",), "got array [0.361]"),
    C_("table-mass", edit(M1, "mass = {kg = 0.361}"), ("link[1].mass",), "got table {kg = 0.361}"),
    C_("date-T2", edit(T2, "T2 = 1979-05-27"), ("controller.T2",), "got date/time 1979-05-27"),
    C_("string-com", edit("com = 0.19 ", 'com = "mid" '), ("link[1].com",), "got string 'mid'"),
    C_("bad-rod-name", edit('inertia = "uniform_rod"', 'inertia = "uniform"'), ("link[1].inertia",),
       "or 'uniform_rod'"),
    C_("description-number", edit(DESC, "description = 42"), ("arm.description",), "one line of printable text"),
    C_("description-comment-end", edit(DESC, 'description = "*/ #include <x.h> /*"'), ("arm.description",),
       "without '*/'"),
    C_("description-two-lines", edit(DESC, 'description = """two\nlines"""'), ("arm.description",),
       "got string 'two\\nlines'"),
    C_("description-backslash", edit(DESC, "description = 'ends in a backslash \\'"), ("arm.description",),
       "contains '\\\\'"),
    C_("description-docstring-end", edit(DESC, "description = 'x\"\"\" + 1'"), ("arm.description",),
       "contains '\"\"\"'"),
    C_("description-trigraph", edit(DESC, 'description = "what??/"'), ("arm.description",), "contains '??/'"),
    C_("description-too-long", edit(DESC, f'description = "{"x" * 201}"'), ("arm.description",),
       "(201 characters)"),
    C_("label-number", edit('label = "second motor"', "label = 2"), ("point_mass[1].label",), "got 2"),
    C_("pm-link-float", edit("link = 1\n", "link = 1.0\n"), ("point_mass[1].link",), "a link number from 1 to 2"),
    C_("pm-link-string", edit("link = 1\n", 'link = "1"\n'), ("point_mass[1].link",), "got string '1'"),
    # non-finite numbers
    C_("nan-torque-constant", edit(KT1, "torque_constant = nan"), ("motor[1].torque_constant",), "not a number",
       cli=True),
    C_("inf-length", edit(L1, "length = inf"), ("link[1].length",), "got inf"),
    C_("1e400-mass", edit(M1, "mass = 1e400"), ("link[1].mass",), "TOML reads 1e400 as inf"),
    C_("minus-inf-gravity", edit("gravity = 0.0", "gravity = -inf"), ("arm.gravity",), "got -inf"),
    C_("nan-pm-inertia", edit("inertia = 0.0            # not given: point mass", "inertia = nan"),
       ("point_mass[1].inertia",), "not a number"),
    C_("huge-integer-mass", edit(M1, "mass = 1" + "0" * 400), ("link[1].mass",), "beyond the range of a double"),
    C_("tiny-fraction-mass", edit(M1, 'mass = "1/1e999"'), ("link[1].mass",), "beyond the range of a double"),
    C_("division-by-zero", edit(T2, 'T2 = "1/0"'), ("controller.T2",), "division by zero"),
    C_("giant-exponent", edit(T2, 'T2 = "1e999999999/1"'), ("controller.T2",), "string '1e999999999/1'"),
    # physically impossible values
    C_("massless-last-link", chain(massless_tip), ("link[2]",), "an inertia about joint 2 > 0"),
    C_("negative-mass", edit(M1, "mass = -0.3"), ("link[1].mass",), "got -0.3", cli=True),
    C_("zero-length", edit(L1, "length = 0"), ("link[1].length",), "> 0 (m), got 0"),
    C_("negative-length", edit(L1, "length = -0.38"), ("link[1].length",), "got -0.38"),
    C_("zero-resistance", edit(R1, "resistance = 0.0"), ("motor[1].resistance",), "> 0 (ohm)"),
    C_("negative-resistance", edit(R1, "resistance = -3.4"), ("motor[1].resistance",), "got -3.4"),
    C_("zero-torque-constant", edit(KT1, "torque_constant = 0"), ("motor[1].torque_constant",), "> 0 (N m/A)"),
    C_("negative-torque-constant", edit(KT1, "torque_constant = -0.23"), ("motor[1].torque_constant",), "-0.23"),
    C_("negative-voltage-constant", edit(KV1, "voltage_constant = -0.29"), ("motor[1].voltage_constant",),
       ">= 0 (V s/rad)"),
    C_("negative-link-inertia", edit('inertia = "uniform_rod"', "inertia = -0.01"), ("link[1].inertia",),
       "got -0.01"),
    C_("negative-pm-inertia", edit("inertia = 0.0            # not given: point mass", "inertia = -1e-3"),
       ("point_mass[1].inertia",), ">= 0 (kg m^2)"),
    C_("negative-rotor-inertia", edit("rotor_inertia = 0.0      #", "rotor_inertia = -1e-6 #"),
       ("motor[1].rotor_inertia",), "got -1e-06"),
    C_("negative-friction", edit("viscous_friction = 0.0   #", "viscous_friction = -0.1 #"),
       ("link[1].viscous_friction",), ">= 0 (N m s/rad)"),
    C_("zero-gear", edit("gear_ratio = 1.0         #", "gear_ratio = 0 #"), ("motor[1].gear_ratio",), "> 0"),
    C_("negative-voltage-limit", chain(lambda d: d["motor"][0].update(voltage_limit=-12.0)),
       ("motor[1].voltage_limit",), "> 0 (V), got -12.0"),
    C_("negative-gravity", edit("gravity = 0.0", "gravity = -9.81"), ("arm.gravity",), ">= 0 (m/s^2)"),
    C_("pm-on-missing-link", edit("link = 2\n", "link = 3\n"), ("point_mass[2].link",), "from 1 to 2, got 3"),
    C_("pm-on-link-zero", edit("link = 1\n", "link = 0\n"), ("point_mass[1].link",), "got 0"),
    C_("hollow-last-link", chain(hollow_tip), ("link[2]",), "J(theta) is singular", cli=True),
    C_("hollow-single-link", chain(hollow_tip, n=1), ("link[1]",), "inertia about joint 1 > 0"),
    # the controller
    C_("T1-above-T2", edit(T1, "T1 = 1.0"), ("controller.T2",), "a number > T1 = 1"),
    C_("T1-equals-T2", edit(T1, 'T1 = "1/1.2"'), ("controller.T2",), "> T1 = 0.833333"),
    C_("negative-T1", edit(T1, "T1 = -0.1"), ("controller.T1",), ">= 0 (s)"),
    C_("zero-T2", chain(both(put(0.0, "controller", "T2"))), ("controller.T2",), "> 0 (s), got 0.0"),
    C_("w1-zero", edit(W, "w = [0.0, 2.0]"), ("controller.w[1]",), "w1 > 0"),
    C_("w1-negative", edit(W, "w = [-1.0, 2.0]"), ("controller.w[1]",), "got -1.0"),
    C_("w2-zero", edit(W, "w = [2.0, 0.0]"), ("controller.w[2]",), "w2 > 0 (observer gain [N m s/rad]"),
    C_("w3-negative", chain(put([1.0, 3.0, -2.0], "controller", "w"), n=3), ("controller.w[3]",), "got -2.0"),
    C_("w-word", edit(W, 'w = "fast"'), ("controller.w",), "or 'auto'"),
    C_("w-full-ragged", edit(W, "w = [[1.0, 0.0], [1.0]]"), ("controller.w",), "an n x n array (a full W)"),
    C_("w-full-diagonal", edit(W, "w = [[1.0, 0.0], [1.0, -2.0]]"), ("controller.w[2][2]",),
       "a diagonal entry > 0 [N m s/rad]"),
    C_("w-full-singular", edit(W, "w = [[1.0, 1.0], [1.0, 1.0]]"), ("controller.w",), "det W = 0"),
    C_("w-full-entry", edit(W, 'w = [[1.0, "x"], [0.0, 1.0]]'), ("controller.w[1][2]",), "got string 'x'"),
    C_("auto-without-speed", edit(W, 'w = "auto"'), ("controller.max_joint_speed",),
       "the speed box [rad/s] W is synthesised for"),
    C_("structure-without-auto", edit(W, W + '\nobserver_structure = "full"'), ("controller.observer_structure",),
       "(w is not 'auto')"),
    C_("structure-unknown", edit(W, 'w = "auto"\nmax_joint_speed = [1.0, 1.0]\nobserver_structure = "diag"'),
       ("controller.observer_structure",), "'chen' or 'full'"),
    C_("rate-negative", edit(W, W + "\nobserver_rate = -1.0"), ("controller.observer_rate",), ">= 0 (1/s)"),
    C_("w-too-short", edit(W, "w = [1.0]"), ("controller.w",), "an array of 2 observer gains"),
    C_("w-too-long", edit(W, "w = [1.0, 2.0, 3.0]"), ("controller.w",), "(3 entries)"),
    C_("w-scalar", edit(W, "w = 1.0"), ("controller.w",), "an array of 2 observer gains w_j > 0 [N m s/rad]"),
    C_("w-entry-string", edit(W, 'w = [1.0, "fast"]'), ("controller.w[2]",), "got string 'fast'"),
    C_("C-wrong-shape", edit(C, "C = [[1.0, 0.0]]"), ("controller.C",), "a 2 x 2 array"),
    C_("C-ragged", edit(C, "C = [[1.0, 0.0], [1.0]]"), ("controller.C",), "2 x 2"),
    C_("C-singular", edit(C, "C = [[1.0, 2.0], [2.0, 4.0]]"), ("controller.C",), "det C = 0", cli=True),
    C_("C-zero", edit(C, "C = [[0, 0], [0, 0]]"), ("controller.C",), "an invertible matrix"),
    C_("C-entry-nan", edit(C, "C = [[1.0, nan], [0.0, 1.0]]"), ("controller.C[1][2]",), "not a number"),
    C_("speed-length", edit(W, W + "\nmax_joint_speed = [1.0]"), ("controller.max_joint_speed",),
       "an array of 2 numbers"),
    C_("speed-negative", edit(W, W + "\nmax_joint_speed = [-1.0, 2.0]"), ("controller.max_joint_speed[1]",),
       "> 0 (rad/s)"),
    # not an arm file at all
    C_("invalid-toml", edit(M1, "mass = "), ("file",), "valid TOML", cli=True),
    C_("link-table-and-array", edit("[[link]]", "[link]"), ("file",), "valid TOML"),
    C_("duplicate-key", edit(M1, M1 + "\nmass = 1.0"), ("file",), "valid TOML"),
    C_("not-utf8", lambda: DEFAULT_TEXT.encode() + b"\n# \xff\xfe\n", ("file",), "UTF-8 text"),
    C_("no-such-file", lambda: None, ("file",), "the name of a packaged arm (glasgow_2link, planar_3link, "
       "vertical_2link), got no such file", cli=True),
    C_("a-folder", lambda: None, ("file",), "a readable arm file", filename="."),
    C_("file-name-docstring-end", lambda: DEFAULT_TEXT, ("file",), "a file name that is one line",
       filename='a"""b.toml'),
    C_("file-name-newline", lambda: DEFAULT_TEXT, ("file",), "contains '\\n'", filename="a\nb.toml", cli=True),
    C_("integer-beyond-python", edit(M1, "mass = " + "9" * 5000), ("file",), "numbers a double can hold"),
    C_("nested-too-deep", append("x = " + "[" * 2000 + "]" * 2000 + "\n"), ("file",), "nested too deeply"),
    C_("oversized-file", append("#" * (1 << 20) + "\n"), ("file",), "at most 1048576 bytes"),
    # several problems at once: all in one message
    C_("many-problems", many_problems,
       ("link[1].mass", "link[1].masse", "motor[1].resistance", "controller.w[2]", "controller.T2",
        "arm.name", "controller.C"), "(7 problems)", cli=True),
]

NAME_CASES = [
    # (id, TOML value or raw source, fragment of the reason)
    ("injection-call", 'x); system("id"); (', "found ')' at position 2"),
    ("comment-include", "*/ #include <x.h> /*", "found '*' at position 1"),
    ("jinja", "{{ 7*7 }}", "found '{'"),
    ("greek-theta", "θ", "U+03B8 GREEK SMALL LETTER THETA"),
    ("greek-in-name", "dθ_arm", "spell Greek letters out"),
    ("c-keyword", "int", "not a C keyword"),
    ("cpp-keyword", "class", "not a C++ keyword"),
    ("cpp-keyword-2", "delete", "not a C++ keyword"),
    ("c-main", "main", "not a C standard library name"),
    ("libm-sin", "sin", "not a C standard library name"),
    ("bessel-j1", "j1", "not a C standard library name"),
    ("posix-type", "size_t", "'_t'"),
    ("path-traversal", "../x", "found '.' at position 1"),
    ("slash", "a/b", "found '/'"),
    ("empty", "", "a non-empty name"),
    ("ten-kilobytes", "a" * 10240, "(10240 characters)"),
    ("thirty-two-characters", "a" * 32, "at most 31 characters"),
    ("capitalised", "Glasgow_2link", "the project requires lowercase names"),
    ("uppercase", "GLASGOW_2LINK", "lowercase"),
    ("nul-byte", "arm\x00x", "U+0000 NUL"),
    ("newline", "arm\nx", "U+000A LINE FEED"),
    ("trailing-newline", "arm\n", "LINE FEED"),
    ("escape", "arm\x1b[2J", "U+001B"),
    ("zero-width-space", "arm\u200b", "ZERO WIDTH SPACE"),
    ("cyrillic-a", "glаsgow", "CYRILLIC SMALL LETTER A"),
    ("fullwidth-g", "ｇlasgow", "which looks like 'g'"),
    ("dotless-i", "maın", "LATIN SMALL LETTER DOTLESS I"),
    ("space", "my arm", "found ' '"),
    ("hyphen", "my-arm", "found '-'"),
    ("leading-digit", "2link", "cannot start with a digit"),
    ("leading-underscore", "_arm", "leading '_' is reserved"),
    ("double-underscore", "a__b", "no '__'"),
    ("trailing-underscore", "arm_", "no trailing '_'"),
    ("casadi-prefix", "casadi_arm", "'casadi'"),
    ("casadi-work-vector", "iw", "CasADi"),
    ("clash-kernel", "glasgow_kernel", "an arm named 'glasgow'"),
    ("clash-kernels", "glasgow_kernels", "does not end in '_kernels'"),
    ("clash-selftest", "glasgow_selftest", "does not end in '_selftest'"),
    ("cmake-target", "clean", "CMake"),
    ("python-keyword", "lambda", "not a Python keyword"),
    ("python-soft-keyword", "match", "not a Python keyword"),
    ("python-builtin", "print", "not a Python builtin"),
    ("python-module", "math", "Python module"),
    ("windows-device", "con", "Windows"),
    ("windows-device-2", "lpt1", "Windows"),
    ("integer", 42, "a string"),
    ("boolean", True, "a string"),
    ("array", ["glasgow_2link"], "got array"),
    ("inline-table", {"first": "glasgow"}, "got table {first = 'glasgow'}"),
]
CLI_NAMES = {"injection-call", "comment-include", "greek-theta", "nul-byte"}

ALL = CASES + [C_(f"name-{i}", name(v), ("arm.name",), frag, cli=i in CLI_NAMES) for i, v, frag in NAME_CASES] + [
    C_("name-as-table-section", lambda: DEFAULT_TEXT.replace('name = "glasgow_2link"\n', "", 1).replace(
        "\n[[link]]", "\n[arm.name]\nfirst = 'glasgow'\n\n[[link]]", 1), ("arm.name",), "got table {first = 'glasgow'}"),
    C_("name-literal-string-injection", name_text("'''x\"); system(\"id\");'''"), ("arm.name",), "found '\"'"),
]


def write(case: Case, tmp_path: Path) -> Path:
    path = tmp_path / case.filename
    content = case.make()
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        path.write_text(content, encoding="utf-8")
    return path


def test_the_table_tries_sixty_or_more_bad_inputs():
    assert len({c.id for c in ALL}) == len(ALL) >= 60


@pytest.mark.parametrize("case", ALL, ids=[c.id for c in ALL])
def test_bad_arm_is_one_spec_error_naming_each_field(case: Case, tmp_path: Path):
    path = write(case, tmp_path)
    with pytest.raises(SpecError, match=re.escape(case.match)) as info:
        derive.load_arm(path)
    err = info.value
    assert sorted(p.field for p in err.problems) == sorted(case.fields), str(err)
    text = str(err)
    assert all(f"  - {p.field}: expected {p.expected}, got {p.given}" in text for p in err.problems)
    assert text.isprintable() or all(line.isprintable() for line in text.splitlines()), text
    assert sorted(p.name for p in tmp_path.iterdir()) == ([path.name] if path.is_file() else [])


@pytest.mark.parametrize("case", [c for c in ALL if c.cli], ids=[c.id for c in ALL if c.cli])
def test_cli_reports_bad_arm_in_one_message_exit_2(case: Case, tmp_path: Path):
    path = write(case, tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = subprocess.run([sys.executable, "-m", "derive", "show", str(path)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stdout == ""
    title = "no such arm" if case.id == "no-such-file" else "invalid arm description"
    assert proc.stderr.startswith(f"derive: error: {title} ")
    for field in case.fields:
        assert f"  - {field}: expected " in proc.stderr, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_every_generated_suffix_is_known_to_names():
    """The names the generated code makes of the arm name are the ones names.py guards."""
    from derive.model.names import GENERATED_SUFFIXES

    folder = ROOT / "generated" / "glasgow_2link"
    text = "\n".join(p.read_text(encoding="utf-8") + "\n" + p.name for p in folder.rglob("*")
                     if p.is_file() and p.suffix != ".png")
    made = {m.lower() for m in re.findall(r"\b(?:glasgow_2link|GLASGOW_2LINK)_(\w+)", text)}
    made = {m.rsplit(".", 1)[0] for m in made}
    assert made and made <= GENERATED_SUFFIXES, sorted(made - GENERATED_SUFFIXES)


@pytest.mark.parametrize("good", ["a", "my_arm", "glasgow_2link", "a" * 31, "arm2_v3", "tool_arm", "kernel"])
def test_valid_names_pass(good: str):
    assert name_problem(good) is None


def test_name_problem_is_one_sentence():
    assert name_problem("int") == "a name that is not a C keyword, got 'int'"
    assert name_problem("x" * 10240).endswith("(10240 characters)")
    assert len(name_problem("x" * 10240)) < 200


def test_names_differing_only_by_case_cannot_both_exist():
    """Only the lowercase spelling is an arm name, so no two arms share a folder on macOS."""
    assert name_problem("glasgow_2link") is None
    for variant in ("Glasgow_2link", "glasgow_2Link", "GLASGOW_2LINK"):
        assert "lowercase" in name_problem(variant)


@pytest.mark.parametrize("data, field", [(None, "arm file"), ([1, 2], "arm file"), ("arm", "arm file"),
                                         ({1: 2}, "1"), ({"arm": None}, "arm")])
def test_arm_from_dict_rejects_non_tables(data, field):
    with pytest.raises(SpecError, match="expected") as info:
        arm_from_dict(data)
    assert field in [p.field for p in info.value.problems]


def test_spec_error_is_a_derive_error_and_a_value_error():
    with pytest.raises(DeriveError, match="link"):
        arm_from_dict({"arm": {"name": "x1"}})
    with pytest.raises(ValueError, match="controller"):
        arm_from_dict({"arm": {"name": "x1"}})


def test_packaged_arms_and_chains_stay_valid():
    for n in (1, 2, 3, 4):
        assert arm_from_dict(chain_dict(n)).n == n
    assert derive.load_arm(None).name == "glasgow_2link"


def _speed_file(tmp_path: Path, speeds: str) -> Path:
    path = tmp_path / "fast.toml"
    path.write_text(DEFAULT_TEXT.replace(W, f"{W}\nmax_joint_speed = {speeds}", 1), encoding="utf-8")
    return path


def test_cli_warns_when_condition_26_limits_the_stated_speed(tmp_path: Path):
    """w1 / X is about 24.7 rad/s for the default arm: 100 rad/s is a warning, not an error."""
    path = _speed_file(tmp_path, "[10.0, 100.0]")
    proc = subprocess.run([sys.executable, "-m", "derive", "show", str(path)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert re.search(r"derive: warning: controller\.max_joint_speed\[2\] = 100 rad/s is not below "
                     r"w1/X = 24\.\d+ rad/s", proc.stderr), proc.stderr
    assert "for (26) = 24.6888   w1/X [rad/s] (eq. 26)" in proc.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fast.toml"]


def test_no_warning_below_the_speed_bound(tmp_path: Path):
    d = derive.derive(derive.load_arm(_speed_file(tmp_path, "[10.0, 20.0]")))
    assert d.warnings == ()
    assert 24 < float(d.speed_bound) < 25


def test_a_bare_name_reads_the_toml_file_of_that_name(tmp_path: Path, monkeypatch):
    """derive show my3 with ./my3.toml present (issue 15.9): the .toml is tried."""
    (tmp_path / "my3.toml").write_text(DEFAULT_TEXT.replace('name = "glasgow_2link"', 'name = "my3"'),
                                       encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert derive.load_arm("my3").name == "my3"
    assert derive.load_arm("glasgow_2link").source.endswith("arms/glasgow_2link.toml")   # packaged first
    with pytest.raises(SpecError, match=re.escape(
            "no such arm my4 (1 problem):\n  - file: expected an arm file (TOML) or the name of a packaged arm "
            "(glasgow_2link, planar_3link, vertical_2link), got no such file (nor my4.toml)")):
        derive.load_arm("my4")
    with pytest.raises(SpecError, match=r"got no such file$"):
        derive.load_arm("my4.toml")


def _every_key(data, field: str = ""):
    """(container, key, field name) of every key of an arm mapping, tables and rows included."""
    for key, value in (data.items() if isinstance(data, dict) else []):
        name = f"{field}.{key}" if field else key
        yield data, key, name
        if isinstance(value, dict):
            yield from _every_key(value, name)
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for i, row in enumerate(value, 1):
                yield from _every_key(row, f"{name}[{i}]")


def _full_default_arm() -> dict:
    """The default arm with every optional key written out (C, simulation, ...)."""
    import tomllib

    data = tomllib.loads(DEFAULT_TEXT)
    data["controller"]["max_joint_speed"] = [20.0, 20.0]
    data["motor"][0]["voltage_limit"] = 12.0
    data["simulation"] = {"duration": 1.0, "seed": 3, "start": [0.0, 1.0]}
    return data


def test_none_is_never_a_value_of_any_key():
    """arm_from_dict mirrors TOML, which has no null: a key set to None (required or
    optional, e.g. controller.C, which defaults to the identity only when left out)
    is a SpecError naming that key, never its default."""
    import copy

    data = _full_default_arm()
    arm_from_dict(data)  # the full mapping is valid
    fields = [name for _, _, name in _every_key(data)]
    assert "controller.C" in fields and "simulation.seed" in fields and len(fields) > 40
    for field in fields:
        spoilt = copy.deepcopy(data)
        container, key, _ = next(c for c in _every_key(spoilt) if c[2] == field)
        container[key] = None
        with pytest.raises(SpecError, match="expected") as info:
            arm_from_dict(spoilt)
        assert field in [p.field for p in info.value.problems], (field, str(info.value))


def test_leaving_C_out_is_the_identity():
    data = _full_default_arm()
    del data["controller"]["C"]
    assert arm_from_dict(data).controller.C == ((1, 0), (0, 1))


def test_none_inside_arrays_and_dh_tables_names_its_place():
    data = _full_default_arm()
    data["controller"]["w"][1] = None
    data["controller"]["C"][0][1] = None
    with pytest.raises(SpecError, match=r"controller\.w\[2\]: expected a value \(TOML has no null") as info:
        arm_from_dict(data)
    assert sorted(p.field for p in info.value.problems) == ["controller.C[1][2]", "controller.w[2]"]
    with pytest.raises(SpecError, match=r"dh\.convention: expected a value .* got nothing: None"):
        arm_from_dict({"arm": {"name": "dh_arm"}, "dh": {"convention": None, "table": [[0, 0, 0, 0]]}})
