"""``derive init robot.urdf``: write a starter arm file for a URDF.

From a URDF to generated C in two commands::

    derive init panda.urdf --tip panda_hand_tcp     # writes panda.toml
    derive generate panda.toml

The arm file takes its chain from the URDF (base link: the root, or --base;
tip link: the unique deepest leaf, or --tip), torque actuation (u is the motor
torque, B = diag(gear ratio)), gear ratio 1 and no rotor inertia, gravity 9.81
m/s^2 along -z of the base, and the default controller settings; every value
the URDF does not give is written as an assumption with a comment, the joint
limits as comments, the chain's notes (merged, locked, normalised) as
comments. It never overwrites a file; the URDF path in it is relative to the
arm file.
"""
from __future__ import annotations

import os
import re
import sys
import tempfile
from fractions import Fraction
from pathlib import Path

from derive.errors import DeriveError, SpecError

T2_DEFAULT = "0.2"
W_DEFAULT = "5.0"


def add_arguments(parser) -> None:
    """CLI: derive init URDF [--base LINK] [--tip LINK] [--out FILE] [--name NAME]."""
    parser.add_argument("urdf", help="the URDF file of the arm")
    parser.add_argument("--base", help="the link the chain starts from (default: the URDF's root link)")
    parser.add_argument("--tip", help="the link the chain ends at (default: the unique deepest leaf)")
    parser.add_argument("--out", help="the arm file to write (default: <urdf name>.toml beside the URDF); "
                        "never overwritten")
    parser.add_argument("--name", help="the arm's name (default: from the URDF's robot name)")
    parser.add_argument("--repair-inertia", action="store_true",
                        help="move each inertia of the chain that is not physical (not positive semi-definite, or "
                        "breaking the triangle inequality) to the nearest physical one and write repair_inertia "
                        "with their links into the arm file (default: refuse them)")


def _name(robot: str, given: str | None) -> str:
    from derive.model.names import name_problem

    if given is not None:
        if (why := name_problem(given)) is not None:
            raise DeriveError(f"--name: expected {why}")
        return given
    name = re.sub(r"[^a-z0-9_]+", "_", robot.lower()).strip("_")
    name = re.sub(r"_+", "_", name)
    if not name or name[0].isdigit():
        name = f"arm_{name}".rstrip("_")
    return name if name_problem(name) is None else f"{name[:26]}_arm" if name_problem(f"{name[:26]}_arm") is None \
        else "my_arm"


def _ends(robot, base: str | None, tip: str | None) -> tuple[str, str]:
    """(base, tip): the given ones, else the root link and the unique deepest leaf."""
    parent = {j.child: j.parent for j in robot.joints}
    links = [link.name for link in robot.links]
    roots = [name for name in links if name not in parent]
    if base is None:
        if len(roots) != 1:
            raise DeriveError(f"{len(roots)} root links ({', '.join(map(repr, roots))}): choose one with --base")
        base = roots[0]
    if tip is None:
        below = {name for name in links if _depth_below(parent, name, base) is not None}
        has_child = {j.parent for j in robot.joints}
        leaves = [(name, _depth_below(parent, name, base)) for name in links if name in below and name not in has_child]
        if not leaves:
            raise DeriveError(f"no link below base link {base!r}: choose the chain's ends with --base and --tip")
        deepest = max(d for _, d in leaves)
        found = [name for name, d in leaves if d == deepest]
        if len(found) > 1:
            raise DeriveError(f"the URDF has {len(found)} deepest leaf links below {base!r} ({deepest} joints down): "
                              f"{', '.join(map(repr, found))}; choose the tip with --tip")
        tip = found[0]
    return base, tip


def _depth_below(parent: dict[str, str], link: str, base: str) -> int | None:
    depth = 0
    while link != base:
        if link not in parent or depth > len(parent):
            return None
        link, depth = parent[link], depth + 1
    return depth


def _num(x: Fraction | None, unit: str) -> str:
    return "none" if x is None else f"{float(x):g} {unit}".rstrip()


def _limits_comment(joint) -> str:
    lim, unit = joint.limits, "m" if not joint.type.rotates else "rad"
    parts = []
    if lim.lower is not None or lim.upper is not None:
        parts.append(f"position [{_num(lim.lower, '')}, {_num(lim.upper, '')}] {unit}")
    if lim.velocity is not None:
        parts.append(f"velocity {_num(lim.velocity, unit + '/s')}")
    if lim.effort is not None:
        parts.append(f"effort {_num(lim.effort, 'N m' if joint.type.rotates else 'N')}")
    return "; ".join(parts) if parts else "no limits in the URDF"


def starter_text(urdf_rel: str, urdf_name: str, name: str, base: str, tip: str, chain, damping,
                 repaired: tuple[str, ...] = ()) -> str:
    """The arm file for a chain read from a URDF (see the module docstring); ``repaired``:
    the links whose inertia ``derive init --repair-inertia`` repaired."""
    n = chain.n
    lines = [
        f"# Arm file written by `derive init` from {urdf_name}. Values the URDF does not give are",
        "# assumptions, marked as such: check them against your hardware. Then: derive generate <this file>",
        "",
        "[arm]",
        f'name = "{name}"',
        f'description = "{name} from {urdf_name}, base {base}, tip {tip}"',
        f'urdf = "{urdf_rel}"',
        f'base_link = "{base}"',
        f'tip_link = "{tip}"',
        "gravity = 9.81                  # m/s^2, assumption: Earth's",
        "gravity_direction = [0, 0, -1]  # assumption: the base link's z axis points up",
        'actuation = "torque"            # u is the motor torque [N m]: B = diag(gear_ratio), no back-EMF',
        "# locked = { joint_name = 0.0 } # hold joints (rad or m); joints off the chain are held at 0",
    ] + ([f"repair_inertia = [{', '.join(chr(34) + x + chr(34) for x in repaired)}]  # their inertias are not "
          "physical: moved to the nearest physical ones (see the notes below)"] if repaired else []) + [
        "",
        "# What reading the URDF did:",
    ]
    lines += [f"#   {note}" for note in chain.notes] or ["#   nothing to note"]
    for i, (joint, bv) in enumerate(zip(chain.joints, damping), 1):
        effort = joint.limits.effort
        lines += [
            "",
            f"[[motor]]  # joint {i}: {joint.name!r} ({joint.type.value}; {_limits_comment(joint)})",
            "gear_ratio = 1.0                # assumption: u is the joint torque",
            "rotor_inertia = 0.0             # kg m^2, assumption: no reflected rotor inertia",
            f"# torque_limit = {float(effort):g}" + " " * max(1, 14 - len(f"{float(effort):g}"))
            + "# N m: the URDF's effort limit; uncomment to clip u" if effort is not None
            else "# torque_limit = 10.0          # N m: uncomment to clip u (the URDF gives no effort limit)",
            f"# viscous_friction = {float(bv):g}" + " " * max(1, 10 - len(f"{float(bv):g}"))
            + "# N m s/rad; default: the URDF's <dynamics damping>",
        ]
    w = ", ".join([W_DEFAULT] * n)
    lines += [
        "",
        "[controller]",
        "T1 = 0.0                        # s, minimum prediction time (eq. 14)",
        f"T2 = {T2_DEFAULT}                        # s, assumption: maximum prediction time (eq. 14); "
        "shorter is stiffer",
        f"w = [{w}]  # 1/s, assumption: observer gains (eq. 25); derive check certifies them on "
        "max_joint_speed, in any order; w = \"auto\" chooses them",
        "",
    ]
    return "\n".join(lines)


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


def run(args) -> int:
    from derive.model.fields import Reader
    from derive.model.spec import SPATIAL_DOWN, gravity_parameter, unit_direction
    from derive.model.urdf import urdf_chain
    from derive.model.urdf_xml import parse_safely

    urdf = Path(args.urdf)
    r = Reader()
    doc = parse_safely(r, str(urdf.resolve()), Path("/"))
    robot = None if doc is None else doc.robot
    if robot is None:
        raise SpecError(str(urdf), [type(p)(p.field.replace("arm.urdf", "urdf"), p.expected, p.given)
                                    for p in r.problems])
    base, tip = _ends(robot, args.base, args.tip)
    table = {"urdf": str(urdf.resolve()), "base_link": base, "tip_link": tip,
             "repair_inertia": bool(getattr(args, "repair_inertia", False))}
    found = urdf_chain(r, table, Path("/"), gravity_parameter(Fraction(981, 100)), unit_direction(SPATIAL_DOWN))
    if found is None:
        raise SpecError(str(urdf), [type(p)(p.field.replace("arm.base_link", "--base").replace(
            "arm.tip_link", "--tip"), p.expected, p.given) for p in r.problems])
    import sympy as sp

    from derive.model.spec import unmoved_inertia

    values = {p.symbol: p.rational for p in found.chain.parameters}
    if (problem := unmoved_inertia(found.chain, [sp.Integer(0)] * found.chain.n, values)) is not None:
        raise SpecError(str(urdf), [problem])   # the starter file (no rotor inertia) would not load
    out = Path(args.out) if args.out else urdf.with_suffix(".toml")
    rel = os.path.relpath(urdf.resolve(), out.resolve().parent).replace(os.sep, "/")
    text = starter_text(rel, urdf.name, _name(robot.name or urdf.stem, args.name), base, tip, found.chain,
                        found.damping, found.repaired)
    _write_new(out, text)
    for p in found.warnings:
        print(f"derive: warning: {p}", file=sys.stderr)
    for note in found.chain.notes:
        if "inertia repaired" in note:
            print(f"derive: note: {note}", file=sys.stderr)
    print(f"derive: wrote {out} ({found.chain.n} joints from {base!r} to {tip!r}); next: derive generate {out}",
          file=sys.stderr)
    return 0
