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
  loop of every form and observer step over the speed box);
* ``observer = "implicit"`` under [controller] (the step derive generate, simulate,
  sweep and fmu build by default) where the forward-Euler step would need a
  sample time below 0.1 ms and the backward-Euler step's limits allow a longer
  one (derive.control.starter.choose_observer); a sample time below 0.1 ms
  that no step avoids is written with the limit that sets it.

It never overwrites a file (checked before the derivation); the URDF path in
it is relative to the arm file.
"""
from __future__ import annotations

import os
import re
import sys
import tempfile
from pathlib import Path

from derive.errors import DeriveError, SpecError
from derive.model.simspec import SimSettings
from derive.cli.init_text import _string, starter_text


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
                             "table and adds the payload's inertia to W and the momentum gains, with the sample time "
                             "it needs, until the linearised sampled loop of DOBC, NPID and MOM holds it at the worst "
                             "centre of mass (derive.control.payload)")
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
    ``payload`` range, W shaped by the payload's inertia until the payload limits cover it: derive.control.payload.design), the start
    pose, the loads and the RK4 substeps (derive.cli.init_numbers); the file named by its absolute path."""
    from derive.cli.init_numbers import choose_gain, rk4_substeps, starter_loads, starter_pose, stated_limits
    from derive.control.starter import choose_observer, fit_to_limits

    gain, _ = choose_gain(starter_text(src, name, notes=notes), out, src.found.chain)
    stated, d = stated_limits(starter_text(src, name, gain=gain, notes=notes), out)
    gain = choose_observer(gain, stated)   # d: the pose, loads and substeps do not depend on the observer step
    momentum, designed, speed_scale = None, (), 1.0
    if payload is not None and payload.mass > 0:
        from derive.control.payload.design import describe, design
        from derive.model.spec import MOMENTUM_GAIN

        def restate(g, K, scale=1.0):
            text = starter_text(src, name, gain=g, notes=notes, momentum=K, payload=payload, speed_scale=scale)
            limits, dd = stated_limits(text, out)
            return fit_to_limits(g, limits), dd

        from derive.progress import progress

        with progress(desc=f"designing for {payload.mass:g} kg", unit="design") as bar:
            def tick(what: str) -> None:
                bar.set_postfix_str(what)
                bar.update()

            pd = design(gain, d, (float(MOMENTUM_GAIN),) * src.found.chain.n, payload, restate, tick)
        if pd.rate != 0.0:
            gain, momentum, d, speed_scale = pd.gain, pd.momentum_gain, pd.derivation, pd.speed_scale
        designed = tuple(describe(pd, payload))
    pose = starter_pose(d)
    loads = starter_loads(d, pose[0] if pose else None)
    plan = rk4_substeps(d, gain.sample_time, pose[0] if pose else None, loads.get("coulomb_friction"))
    substeps = plan.substeps if plan.substeps > SimSettings.substeps else None
    return starter_text(src, name, gain=gain, notes=notes, substeps=substeps, pose=pose, loads=loads, payload=payload,
                        momentum=momentum, designed=designed, speed_scale=speed_scale,
                        widening=plan if plan.widened else None)   # defaults unsaid


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
