"""``derive init robot.urdf``: write a starter arm file for a URDF.

From a URDF to generated C in two commands::

    derive init panda.urdf --tip panda_hand_tcp     # writes panda.toml
    derive generate panda.toml

The arm file takes its chain from the URDF (base link: the root, or --base;
tip link: the unique deepest leaf, or --tip), torque actuation (u is the motor
torque, B = diag(gear ratio)), gear ratio 1 and no rotor inertia, gravity 9.81
m/s^2 along -z of the base; every value the URDF does not give is written as an
assumption with a comment, the joint limits as comments, the chain's notes
(merged, locked, normalised) as comments. It works as written:

* ``max_joint_speed``: the URDF's velocity limits (DEFAULT_SPEED rad/s, an
  assumption noted, where it gives none): the box the observer certificate and
  the sample-time limits cover;
* ``torque_limit``: each joint's effort limit (u is clipped to it);
* ``w``: W = omega Jbar for this arm (derive.control.starter), certified on the
  box by the same decision ``derive check`` makes;
* ``[simulation] sample_time``: a round value at most 0.45 of the limits
  estimated from W's largest observer rate and the momentum observer's gain, and
  at most half of every limit ``derive show`` states for the file (the sampled
  loop of every form and observer step over the speed box).

It never overwrites a file (checked before the derivation); the URDF path in
it is relative to the arm file.
"""
from __future__ import annotations

import os
import re
import sys
import tempfile
from fractions import Fraction
from pathlib import Path

from derive.cli.init_numbers import DEFAULT_SPEED, DEFAULT_TRAVEL_SPEED, speed_box
from derive.errors import DeriveError, SpecError
from derive.model.simspec import SimSettings

T2_DEFAULT = "0.2"
DIGITS = 4                   # significant digits of W as written (derive.control.starter.DIGITS)


def add_arguments(parser) -> None:
    """CLI: derive init FILE [--base LINK] [--tip LINK] [--out FILE] [--name NAME] [--xacro-arg NAME:=VALUE]."""
    parser.add_argument("urdf", metavar="FILE", help="the arm's URDF, xacro (.xacro; expanded by the xacro package) "
                        "or MJCF (MuJoCo's XML, root element <mujoco>) file")
    parser.add_argument("--base", help="the link (MJCF: body) the chain starts from (default: the root)")
    parser.add_argument("--tip", help="the link (MJCF: body) the chain ends at (default: the unique deepest leaf)")
    parser.add_argument("--out", help="the arm file to write (default: <file name>.toml beside the file); "
                        "never overwritten")
    parser.add_argument("--name", help="the arm's name (default: the URDF's robot name or the MJCF's model name, "
                        "else the file's name)")
    parser.add_argument("--xacro-arg", action="append", metavar="NAME:=VALUE",
                        help="an argument of a xacro file (repeat it for several, e.g. --xacro-arg ur_type:=ur10e); "
                        "the expanded URDF is written beside the arm file")
    parser.add_argument("--payload", metavar="MASS",
                        help="design for payloads from 0 to MASS kg (the vendor's rated payload): writes a [payload] "
                             "table and scales W, the momentum gains and the sample time until the linearised sampled "
                             "loop of DOBC, NPID and MOM holds it at the worst centre of mass (derive.control.payload)")
    parser.add_argument("--payload-com", metavar="X,Y,Z", default="0,0,0",
                        help="the payload's nominal centre of mass in the tip link's frame [m] (default 0,0,0)")
    parser.add_argument("--payload-radius", metavar="R", default="0.15",
                        help="the ball around --payload-com the centre of mass may lie in [m] (default 0.15)")
    parser.add_argument("--repair-inertia", action="store_true",
                        help="move each inertia of the chain that is not physical (not positive semi-definite, or "
                        "breaking the triangle inequality) to the nearest physical one and write repair_inertia "
                        "with their links into the arm file (default: refuse them)")


def _name(robot: str, given: str | None, what: str = "the URDF's robot name") -> tuple[str, str | None]:
    """The arm's name: ``given`` (--name, checked), else ``robot`` (``what``: where it is from) made a
    safe C identifier (derive.model.names); with a note giving both names when that changed it."""
    from derive.model.names import name_problem

    if given is not None:
        if (why := name_problem(given)) is not None:
            raise DeriveError(f"--name: expected {why}")
        return given, None
    name = re.sub(r"[^a-z0-9_]+", "_", robot.lower()).strip("_")
    name = re.sub(r"_+", "_", name)
    if not name or name[0].isdigit():
        name = f"arm_{name}".rstrip("_")
    name = name if name_problem(name) is None else f"{name[:26]}_arm" if name_problem(f"{name[:26]}_arm") is None \
        else "my_arm"
    if name == robot:
        return name, None
    shown = repr(robot) if len(robot) <= 100 else f"{robot[:100]!r}... ({len(robot)} characters)"
    return name, (f"{what} {shown} is not a name derive can use (a C identifier of lowercase "
                  f"ASCII letters, digits and '_'): the arm is named {name!r} (--name chooses another)")


def _num(x: Fraction | None, unit: str) -> str:
    return "none" if x is None else f"{float(x):g} {unit}".rstrip()


def _limits_comment(joint, word: str = "URDF") -> str:
    lim, unit = joint.limits, "m" if not joint.type.rotates else "rad"
    parts = []
    if lim.lower is not None or lim.upper is not None:
        parts.append(f"position [{_num(lim.lower, '')}, {_num(lim.upper, '')}] {unit}")
    if lim.velocity is not None:
        parts.append(f"velocity {_num(lim.velocity, unit + '/s')}")
    if lim.effort is not None:
        parts.append(f"effort {_num(lim.effort, 'N m' if joint.type.rotates else 'N')}")
    return "; ".join(parts) if parts else f"no limits in the {word}"


def _g(x: float) -> str:
    return f"{x:.{DIGITS}g}"


def _string(text: str) -> str:
    """``text`` as a TOML basic string: a link or file name with a quote, a backslash or a control
    character (U+0000-U+001F, U+007F: TOML's backslash-u escape, four hex digits) stays one string."""
    def escape(c: str) -> str:
        if c in '"\\':
            return "\\" + c
        return f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c
    return '"' + "".join(escape(c) for c in text) + '"'


def _description(name: str, urdf_name: str, base: str, tip: str) -> str:
    """The arm's description: its name, the URDF file's and the chain's ends, without the names
    that could not stand in a generated C comment or docstring (derive.model.fields.text_problem)."""
    from derive.model.fields import text_problem

    for text in (f"{name} from {urdf_name}, base {base}, tip {tip}", f"{name} from {urdf_name}"):
        if text_problem(text) is None:
            return text
    return f"{name} from a URDF"


def _vector(values) -> str:
    return "[" + ", ".join(repr(float(x)) if x != int(x) else str(int(x)) for x in values) + "]"


def starter_text(src, name: str, rel: str | None = None, gain=None, notes: tuple[str, ...] = (),
                 substeps: int | None = None, pose=None, loads=None, payload=None, momentum=None,
                 designed: tuple[str, ...] = ()) -> str:
    """The arm file for the chain of ``src`` (derive.cli.init_source.Source; see the module
    docstring), naming ``rel`` (the file's path relative to the arm file; default: ``src.path``).
    ``gain``: the derive.control.starter.StarterGain to write (None: a draft whose W is J's
    scale-free placeholder, for reading the chain back). ``notes``: init's own notes (the
    name's), written before the chain's. ``payload``: the [payload] range to write
    (derive.model.payload.PayloadRange), ``momentum``: the momentum observer's gains K when not the
    default, ``designed``: the comment lines of the payload design (derive.control.payload.design)."""
    chain, found, word = src.found.chain, src.found, src.word
    key, base_key, tip_key = src.keys
    n = chain.n
    box, assumed = speed_box(chain)
    if src.assumed_gravity:
        gravity = ["gravity = 9.81                  # m/s^2, assumption: Earth's",
                   "gravity_direction = [0, 0, -1]  # assumption: the base link's z axis points up"]
    else:
        gravity = [f"gravity = {src.gravity!r}" + " " * max(1, 22 - len(f"{src.gravity!r}"))
                   + f"# m/s^2: the {word}'s <option gravity>",
                   f"gravity_direction = {_vector(src.direction)}  # the {word}'s gravity in the base body's frame"]
    lines = [
        f"# Arm file written by `derive init` from {src.shown}. Values the {word} does not give are",
        "# assumptions, marked as such: check them against your hardware. Then: derive generate <this file>",
    ] + ([f"# {rel or src.path} is the expansion of `{src.xacro}` by the xacro package"] if src.xacro else []) + [
        "",
        "[arm]",
        f"name = {_string(name)}",
        f"description = {_string(_description(name, src.shown, src.base, src.tip))}",
        f"{key} = {_string(rel if rel is not None else str(src.path.resolve()))}",
        f"{base_key} = {_string(src.base)}",
        f"{tip_key} = {_string(src.tip)}",
        *gravity,
        'actuation = "torque"            # u is the motor torque [N m]: B = diag(gear_ratio), no back-EMF',
        "# locked = { joint_name = 0.0 } # hold joints (rad or m); joints off the chain are held at 0",
    ] + ([f"repair_inertia = [{', '.join(map(_string, found.repaired))}]  # their inertias are not "
          "physical: moved to the nearest physical ones (see the notes below)"] if found.repaired else []) + [
        "",
        f"# What reading the {word} did:",
    ]
    lines += [f"#   {note}" for note in (*notes, *chain.notes)] or ["#   nothing to note"]
    armature = found.armature or (0,) * n
    for i, (joint, bv, a) in enumerate(zip(chain.joints, found.damping, armature), 1):
        effort = joint.limits.effort
        unit = "N m" if joint.type.rotates else "N"
        rotor = (f"rotor_inertia = {float(a):g}" + " " * max(1, 15 - len(f"{float(a):g}"))
                 + f"# kg m^2: the {word}'s armature (the rotor inertia reflected to the joint)") if a else \
            "rotor_inertia = 0.0             # kg m^2, assumption: no reflected rotor inertia"
        limit = "effort limit" if src.kind == "urdf" else "actuator force limit"
        damping = "<dynamics damping>" if src.kind == "urdf" else "damping"
        lines += [
            "",
            f"[[motor]]  # joint {i}: {joint.name!r} ({joint.type.value}; {_limits_comment(joint, word)})",
            "gear_ratio = 1.0                # assumption: u is the joint torque",
            rotor,
            f"torque_limit = {float(effort):g}" + " " * max(1, 16 - len(f"{float(effort):g}"))
            + f"# {unit}: the {word}'s {limit}; u is clipped to it" if effort is not None and effort > 0
            else f"# torque_limit = 10.0          # {unit}: uncomment to clip u (the {word} gives no effort limit)",
            f"# viscous_friction = {float(bv):g}" + " " * max(1, 10 - len(f"{float(bv):g}"))
            + f"# {unit} s/{'rad' if joint.type.rotates else 'm'}; default: the {word}'s {damping}",
        ]
    speeds = ", ".join(f"{v:g}" for v in box)
    guessed = [str(i) for i, a in enumerate(assumed, 1) if a]
    if guessed:
        source = (f"the {word}'s velocity limits; joint{'s' if len(guessed) > 1 else ''} {', '.join(guessed)}: "
                  f"assumption, {DEFAULT_SPEED:g} rad/s ({DEFAULT_TRAVEL_SPEED:g} m/s if prismatic), the {word} "
                  "gives no velocity limit")
    else:
        source = f"the {word}'s velocity limits"
    lines += [
        "",
        "[controller]",
        "T1 = 0.0                        # s, minimum prediction time (eq. 14)",
        f"T2 = {T2_DEFAULT}                        # s, assumption: maximum prediction time (eq. 14); "
        "shorter is stiffer",
        f"max_joint_speed = [{speeds}]  # rad/s (m/s prismatic): {source}; derive check certifies the "
        "observer on this box, and the sample-time limits cover it",
    ]
    if gain is None:
        lines.append(f"w = [{', '.join(['1.0'] * n)}]")
        return "\n".join(lines) + "\n"
    lo, hi = gain.rates
    rows = ",\n     ".join("[" + ", ".join(_g(x) for x in row) + "]" for row in gain.W)
    lines += [
        "# The observer gain W (eq. 25; a full n x n W) [N m s/rad, N s/m on a prismatic joint's row: p = W theta'",
        "# is a joint torque, eq. 21-22]: W = omega Jbar,",
        "# Jbar the mean of J over the joint ranges, so that the observer rates, the eigenvalues of W J^-1",
        f"# (eq. 24), spread only as far as J does: {_g(lo)} ... {_g(hi)} 1/s over the ranges (omega = {_g(gain.omega)} 1/s),",
        ("# what puts the rates' geometric mean at 20 1/s, more than the observer certificate needs on" if gain.floor
         else "# the smallest omega the observer certificate proves on max_joint_speed, with a margin"),
        ("# max_joint_speed" if gain.floor else "#")
        + f" (its decision: {gain.decision.verdict.value}, {gain.decision.cells} cells).",
        "# Replace it by your own, or by w = \"auto\" (derive tune prints the smallest ||W||).",
        f"w = [{rows}]",
    ] + ([f"momentum_gain = [{', '.join(f'{x:.4g}' for x in momentum)}]  # 1/s: the momentum observer's K (r' = K (B d - r)), the "
          "default 50 scaled with W for the payload"] if momentum is not None else []) + [
        "",
        "[simulation]",
        f"sample_time = {gain.sample_time:g}" + " " * max(1, 20 - len(f"{gain.sample_time:g}"))
        + "# s: a round value at most 0.45 of each limit estimated from W and the momentum observer's",
        f"# gain (the forward-Euler observer step is stable below 2 / {_g(hi)} 1/s, 0.9 x: "
        f"{gain.observer_limit * 1e3:.3g} ms;",
        f"# the momentum observer's below 2 / K, {gain.momentum_limit * 1e3:.3g} ms), and at most half of each "
        "limit derive show",
        "# and derive check state for this file (the sampled loop over the speed box, 0.9 of the largest stable):",
    ] + _stated_lines(gain.stated)
    if pose is not None:
        theta0, amp = pose
        lines += [
            f"initial_theta = [{', '.join(_g(x) for x in theta0)}]  # rad (m prismatic): the start pose, chosen so that",
            "# the experiment's gravity torques stay within 0.8 of the effort limits, the pose 5 % of each joint's",
            "# travel inside its limits and every pulse inside its joint's range (the zero pose did not:",
            "# derive.cli.init_numbers.starter_pose)",
            'reference_start = "measured"    # y_d starts at the start pose; the pulses are offsets from it',
            f"amplitude = [{', '.join(_g(x) for x in amp)}]  # rad (m prismatic): each joint's pulse, at most 90 deg (half",
            "# the travel of a prismatic joint) and 0.8 of the room between the start and the upper limit",
        ]
    for key, values in (loads or {}).items():
        lines += [
            f"{key} = [{', '.join(_g(x) for x in values)}]  # N m (N prismatic): the default's, at most 5 rad/s^2",
            "# times each joint's inertia at the start pose (a light joint is not thrown by a load of the paper's",
            "# arm's size: derive.cli.init_numbers.starter_loads)",
        ]
    if substeps is not None:
        lines += [
            f"substeps = {substeps}" + " " * max(1, 20 - len(str(substeps)))
            + "# RK4 steps per sample: the plant's stiffest mode at the initial pose (the joints' friction",
            "# as a smooth Coulomb law, its slope over the joint inertia) needs h lambda <= 2.785",
        ]
    if payload is not None:
        c = ", ".join(_g(x) for x in payload.com)
        lines += ["", "[payload]",
                  f"mass = {_g(payload.mass)}" + " " * max(1, 22 - len(_g(payload.mass)))
                  + "# kg: the controller must hold every payload from 0 to this (derive init --payload)",
                  f"com = [{c}]" + " " * max(1, 20 - len(c)) + "# m, in the tip link's frame: the nominal centre of mass",
                  f"com_radius = {_g(payload.com_radius)}" + " " * max(1, 16 - len(_g(payload.com_radius)))
                  + "# m: the centre of mass may lie anywhere within this ball around com",
                  "# inertia = [[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]  # kg m^2 about the centre of mass "
                  "at mass; default: a solid sphere of 5 cm radius", *designed]
    return "\n".join(lines + [""])


def _stated_lines(stated) -> list[str]:
    """Comment lines of the sampled loop's limits (StarterGain.stated), per observer step."""
    def ms(x: float) -> str:
        return "none" if x == 0 else "any" if x == float("inf") else f"{x * 1e3:.3g} ms"

    out = []
    for observer, label in (("explicit", "forward-Euler observer step (derive generate's default)"),
                            ("implicit", "--observer implicit")):
        forms = [(f, x) for o, f, x in stated if o == observer]
        if forms:
            out.append(f"#   {label}: " + ", ".join(f"{f.upper()} {ms(x)}" for f, x in forms))
    return out


def _write_new(path: Path, text: str) -> None:
    """Write ``text`` to ``path``, never replacing a file: a temporary file in the same
    folder, then a hard link to the final name (fails if it exists)."""
    if path.exists() or path.is_symlink():
        raise DeriveError(f"--out {path}: expected a file that does not exist yet, got an existing one; "
                          "derive init never overwrites (remove it or choose another --out)")
    folder = path.parent
    try:
        fd, tmp = tempfile.mkstemp(prefix=".derive-init-", suffix=".toml", dir=folder)
    except OSError as exc:
        raise DeriveError(f"--out {path}: cannot write in {folder} ({exc.strerror or exc})") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.chmod(tmp, 0o666 & ~_umask())
        os.link(tmp, path)
    except FileExistsError:
        raise DeriveError(f"--out {path}: expected a file that does not exist yet, got an existing one") from None
    except OSError as exc:
        raise DeriveError(f"--out {path}: cannot write it ({exc.strerror or exc})") from None
    finally:
        os.unlink(tmp)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _numbers(src, name: str, notes: tuple[str, ...], out: Path, payload=None) -> str:
    """The starter text with its numbers: W and the sample time, fitted to the stated limits (and, with a
    ``payload`` range, scaled until the payload limits cover it: derive.control.payload.design), the start
    pose, the loads and the RK4 substeps (derive.cli.init_numbers); the file named by its absolute path."""
    from derive.cli.init_numbers import choose_gain, rk4_substeps, starter_loads, starter_pose, stated_limits
    from derive.control.starter import fit_to_limits

    gain, _ = choose_gain(starter_text(src, name, notes=notes), out, src.found.chain)
    stated, d = stated_limits(starter_text(src, name, gain=gain, notes=notes), out)
    gain = fit_to_limits(gain, stated)
    momentum, designed = None, ()
    if payload is not None and payload.mass > 0:
        from derive.control.payload.design import describe, design
        from derive.model.spec import MOMENTUM_GAIN

        def restate(g, K):
            text = starter_text(src, name, gain=g, notes=notes, momentum=K, payload=payload)
            limits, dd = stated_limits(text, out)
            return fit_to_limits(g, limits), dd

        pd = design(gain, d, (float(MOMENTUM_GAIN),) * src.found.chain.n, payload, restate)
        if pd.factor != 1.0:
            gain, momentum = pd.gain, pd.momentum_gain
            _, d = restate(gain, momentum)
        designed = tuple(describe(pd, payload))
    pose = starter_pose(d)
    loads = starter_loads(d, pose[0] if pose else None)
    substeps = rk4_substeps(d, gain.sample_time, pose[0] if pose else None, loads.get("coulomb_friction"))
    return starter_text(src, name, gain=gain, notes=notes, substeps=substeps if substeps > SimSettings.substeps
                        else None, pose=pose, loads=loads, payload=payload, momentum=momentum,
                        designed=designed)   # defaults unsaid


def _payload_range(args):
    """The [payload] range of ``--payload MASS`` (with --payload-com, --payload-radius), or None;
    DeriveError (exit 2) for an impossible value, before anything is read or written."""
    if args.payload is None:
        return None
    import math

    from derive.model.fields import Reader
    from derive.model.payload import parse_payload

    def number(text: str, option: str) -> float:
        try:
            x = float(text)
        except ValueError:
            raise DeriveError(f"{option}: expected a finite number, got {text!r}") from None
        if not math.isfinite(x):
            raise DeriveError(f"{option}: expected a finite number, got {text!r}")
        return x

    com = [number(x, "--payload-com") for x in args.payload_com.split(",")]
    table = {"mass": number(args.payload, "--payload"), "com": com,
             "com_radius": number(args.payload_radius, "--payload-radius")}
    r = Reader()
    rng = parse_payload(r, table, "payload")
    if r.problems:
        p = r.problems[0]
        option = {"payload.mass": "--payload", "payload.com_radius": "--payload-radius"}.get(p.field, "--payload-com")
        raise DeriveError(f"{option}: expected {p.expected}, got {p.given}")
    return rng


def _default_out(path: Path) -> Path:
    """<file name>.toml beside the file (``ur.urdf.xacro`` -> ``ur.toml``)."""
    stem = path.name
    for suffix in (".urdf.xacro", ".xacro", ".urdf", ".xml"):
        if stem.endswith(suffix) and len(stem) > len(suffix):
            stem = stem[:-len(suffix)]
            break
    else:
        stem = path.stem or stem
    return path.parent / f"{stem}.toml"


def run(args) -> int:
    import sympy as sp

    from derive.cli.init_source import read_source
    from derive.model.rigid import rational
    from derive.model.spec import unmoved_inertia

    given = Path(args.urdf)
    if args.out and not Path(args.out).parent.is_dir():   # before reading anything
        raise DeriveError(f"--out: expected a file in an existing folder, got {args.out} "
                          f"(no folder {Path(args.out).parent})")
    out = Path(args.out) if args.out else _default_out(given)
    payload = _payload_range(args)   # before reading anything
    with tempfile.TemporaryDirectory(prefix="derive-init-") as scratch:
        src = read_source(args, Path(scratch))
        found = src.found
        expanded = out.with_suffix(".urdf") if src.expanded is not None else None
        values = {p.symbol: p.rational for p in found.chain.parameters}
        rotors = [rational(a) for a in found.armature] or [sp.Integer(0)] * found.chain.n
        if (problem := unmoved_inertia(found.chain, rotors, values)) is not None:
            raise SpecError(str(given), [problem])   # the starter file would not load
        for path in (out, expanded):   # before the minutes the derivation may take
            if path is not None and (path.exists() or path.is_symlink()):
                _write_new(path, "")
        name, renamed = _name(src.robot or src.path.name.split(".")[0], args.name, src.whence)
        notes = (renamed,) if renamed else ()
        text = _numbers(src, name, notes, out, payload)
        final = expanded.name if expanded is not None else \
            os.path.relpath(src.path.resolve(), out.resolve().parent).replace(os.sep, "/")
        text = text.replace(f" = {_string(str(src.path.resolve()))}\n", f" = {_string(final)}\n", 1)
        if expanded is not None:
            _write_new(expanded, src.expanded)
        try:
            _write_new(out, text)
        except DeriveError:
            if expanded is not None:
                expanded.unlink()   # nothing half-written
            raise
    for p in found.warnings:
        print(f"derive: warning: {p}", file=sys.stderr)
    for note in notes:
        print(f"derive: note: {note}", file=sys.stderr)
    for note in found.chain.notes:
        if "inertia repaired" in note:
            print(f"derive: note: {note}", file=sys.stderr)
    if expanded is not None:
        print(f"derive: wrote {expanded} (the expansion of {src.xacro})", file=sys.stderr)
    base, tip = src.base, src.tip
    print(f"derive: wrote {out} ({found.chain.n} joints from {base!r} to {tip!r}); next: derive generate {out}",
          file=sys.stderr)
    return 0
