"""What ``derive init`` reads: a URDF, a xacro file expanded to a URDF, or an MJCF, as one
:class:`Source` (the file the arm file names, the chain's ends, the chain, the gravity).

* URDF (root element ``<robot>``): derive.model.urdf; base: the root link, tip: the unique
  deepest leaf, unless given; gravity 9.81 m/s^2 along -z of the base (an assumption).
* xacro (a ``.xacro`` file, or any file with ``--xacro-arg``): expanded by the ``xacro``
  package (ROS's, from PyPI: ``pip install 'derive[xacro]'``) with the ``--xacro-arg NAME:=VALUE``
  arguments, then read as a URDF; the arm file names the expanded URDF, which ``init`` writes
  beside it (never overwriting). ``$(find pkg)`` is the nearest folder above the file named ``pkg``
  or holding a ``package.xml`` of that name (a ROS package checked out without ROS), else ROS's
  own lookup.
* MJCF (root element ``<mujoco>``): derive.model.mjcf; ``--base``/``--tip`` are body names
  (base: the one body under the world body, tip: the unique deepest leaf, unless given); gravity
  is the MJCF's ``<option gravity>`` turned into the base body's frame at the model pose.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

from derive.errors import DeriveError, SpecError

XACRO_INSTALL = "pip install 'derive[xacro]'"
# rad: rpy angles at most this far from a multiple of pi/2 (and more than derive.model.rigid.SNAP_TOLERANCE) are
# the exporter's rounding of it (1.5708: 3.7e-6 rad; 1.571: 2.0e-4 is not taken): the starter writes the
# [arm] snap_angles that takes them as that multiple (derive.model.rigid.snapping), said in the file
INIT_SNAP = 1e-4
_ARG = re.compile(r"([A-Za-z_][A-Za-z0-9_]*):=(.*)\Z", re.S)


@dataclass(frozen=True)
class Source:
    """The file an arm file takes its chain from: ``kind`` ("urdf" or "mjcf"), ``path`` (the file
    the arm file names), ``shown`` (its name for comments), ``robot`` (the file's own name of the
    robot, "" when it has none) and ``whence`` (what that name is), the chain's ``base`` and
    ``tip``, ``found`` (derive.model.urdf.UrdfChain), ``gravity`` [m/s^2] and ``direction`` (in
    the base frame) with whether they are assumed, ``expanded`` (a xacro's URDF text, written
    beside the arm file; None otherwise) and ``xacro`` (the xacro file and arguments, for a comment)."""

    kind: str
    path: Path
    shown: str
    robot: str
    whence: str
    base: str
    tip: str
    found: Any
    gravity: float = 9.81
    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    assumed_gravity: bool = True
    expanded: str | None = None
    xacro: str = ""
    snap: float | None = None   # [arm] snap_angles the starter writes (INIT_SNAP), None: as written

    @property
    def word(self) -> str:
        return "MJCF" if self.kind == "mjcf" else "URDF"

    @property
    def keys(self) -> tuple[str, str, str]:
        """The arm-file keys of the file, the base and the tip."""
        return ("mjcf", "base_body", "tip_body") if self.kind == "mjcf" else ("urdf", "base_link", "tip_link")


def ends(parent: dict[str, str], names: list[str], base: str | None, tip: str | None,
         what: str = "link") -> tuple[str, str]:
    """(base, tip): the given ones, else the root and the unique deepest leaf below it; ``parent``:
    child -> parent of the tree's ``names`` (links, or bodies)."""
    roots = [name for name in names if name not in parent]
    plural = "bodies" if what == "body" else f"{what}s"
    if base is None:
        if len(roots) != 1:
            raise DeriveError(f"{len(roots)} root {plural} ({', '.join(map(repr, roots))}): choose one with --base")
        base = roots[0]
    if tip is None:
        depth = {name: _depth_below(parent, name, base) for name in names}
        has_child = set(parent.values())
        leaves = [(name, d) for name, d in depth.items() if d is not None and name not in has_child]
        if not leaves:
            raise DeriveError(f"no {what} below base {what} {base!r}: choose the chain's ends with --base and --tip")
        deepest = max(d for _, d in leaves)
        found = [name for name, d in leaves if d == deepest]
        if len(found) > 1:
            raise DeriveError(f"the file has {len(found)} deepest leaf {plural} below {base!r} ({deepest} "
                              f"{'joints' if what == 'link' else 'bodies'} down): {', '.join(map(repr, found))}; "
                              "choose the tip with --tip")
        tip = found[0]
    return base, tip


def _depth_below(parent: dict[str, str], link: str, base: str) -> int | None:
    depth = 0
    while link != base:
        if link not in parent or depth > len(parent):
            return None
        link, depth = parent[link], depth + 1
    return depth


def _fail(path: Path, problems, renames=()) -> SpecError:
    out = []
    for p in problems:
        f = p.field
        for a, b in renames:
            f = f.replace(a, b)
        out.append(type(p)(f, p.expected, p.given))
    return SpecError(str(path), out)


def _root_tag(path: Path) -> str | None:
    """The root element's name of an XML file (read safely), or None when it cannot be told."""
    import defusedxml.ElementTree as safe

    try:
        for _, element in safe.iterparse(str(path), events=("start",), forbid_dtd=True, forbid_entities=True,
                                         forbid_external=True):
            return element.tag
    except Exception:  # noqa: BLE001 - unreadable or malformed: the reader gives its own message
        return None
    return None


def expand_xacro(path: Path, args: list[str]) -> str:
    """The URDF text of the xacro file ``path`` with ``args`` (NAME:=VALUE each); DeriveError (exit 2)
    when the package is missing, an argument is malformed, or xacro cannot expand the file."""
    mappings = {}
    for arg in args:
        m = _ARG.match(arg)
        if m is None:
            raise DeriveError(f"--xacro-arg: expected NAME:=VALUE (a xacro argument, e.g. ur_type:=ur10e), got {arg!r}")
        mappings[m[1]] = m[2]
    try:
        import xacro
    except ImportError as exc:
        raise DeriveError(f"{path}: expected the xacro package to expand a xacro file (install it with "
                          f"{XACRO_INSTALL}), got {type(exc).__name__}: {exc}") from None
    if not path.is_file():
        raise DeriveError(f"{path}: expected a readable xacro file, got no such file")
    import contextlib
    import io

    said = io.StringIO()
    from xacro import substitution_args

    ros_find = substitution_args._eval_find
    substitution_args._eval_find = lambda pkg: _package_folder(path, pkg, ros_find)
    try:
        with contextlib.redirect_stderr(said), contextlib.redirect_stdout(said):
            doc = xacro.process_file(str(path), mappings=mappings)
    except Exception as exc:  # noqa: BLE001 - xacro raises XacroException, OSError, NameError, ... with its message
        from derive.model.urdf_xml import clip

        raise DeriveError(f"{path}: expected a xacro file the xacro package expands with "
                          f"{', '.join(args) or 'no arguments'}, got {type(exc).__name__}: {clip(str(exc))}") from None
    finally:
        substitution_args._eval_find = ros_find
    return doc.toprettyxml(indent="  ")


def _package_folder(path: Path, pkg: str, ros_find) -> str:
    """``$(find pkg)`` without a ROS installation: the nearest folder above the xacro file named ``pkg``
    or holding a package.xml whose <name> is ``pkg``; else ROS's own lookup (ament), whose failure xacro
    reports."""
    import re

    for folder in path.resolve().parents:
        manifest = folder / "package.xml"
        if folder.name == pkg or (manifest.is_file() and re.search(
                rf"<name>\s*{re.escape(pkg)}\s*</name>", manifest.read_text(errors="replace"))):
            return str(folder)
    try:
        return ros_find(pkg)
    except ImportError:
        raise LookupError(f"$(find {pkg}): no folder above {path.name} is named {pkg!r} or holds its package.xml, "
                          "and ROS's package index (ament_index_python) is not installed") from None


def read_source(args, scratch: Path) -> Source:
    """The file of ``derive init``'s arguments read (module docstring); a xacro's expansion is
    written into the folder ``scratch`` to be read. SpecError/DeriveError (exit 2) on bad input."""
    path = Path(args.urdf)
    xacro_args = list(getattr(args, "xacro_arg", None) or [])
    if path.suffix == ".xacro" or xacro_args:
        text = expand_xacro(path, xacro_args)
        target = scratch / (path.name.removesuffix(".xacro") if path.name.endswith(".urdf.xacro")
                            else path.stem + ".urdf")
        target.write_text(text, encoding="utf-8")
        shown = f"{path.name} ({' '.join(xacro_args) or 'no arguments'})"
        return _urdf(args, target, target.name, text, f"xacro {path.name} {' '.join(xacro_args)}".rstrip(), shown)
    if _root_tag(path) == "mujoco":
        return _mjcf(args, path)
    return _urdf(args, path, path.name)


def _urdf(args, path: Path, shown: str, expanded: str | None = None, xacro: str = "",
          described: str | None = None) -> Source:
    from derive.model.fields import Reader
    from derive.model.spec import SPATIAL_DOWN, gravity_parameter, unit_direction
    from derive.model.urdf import urdf_chain
    from derive.model.urdf_elements import snap_suggestion
    from derive.model.urdf_xml import parse_safely

    r = Reader()
    doc = parse_safely(r, str(path), Path.cwd(), "the path as given on the command line")
    if doc is None:
        raise _fail(path, r.problems, (("arm.urdf", "urdf"),))
    robot = doc.robot
    base, tip = ends({j.child: j.parent for j in robot.joints}, [link.name for link in robot.links], args.base,
                     args.tip)
    # repair_inertia absent unless asked for, as in the file written: its draft then finds this chain kept
    # (derive.model.urdf.urdf_chain's key: 0.1-0.2 s of reading on 7 joints)
    table = {"urdf": str(path.resolve()), "base_link": base, "tip_link": tip,
             "repair_inertia": True if getattr(args, "repair_inertia", False) else None}

    def chain(snap: float | None = None):
        found = urdf_chain(r, {**table, "snap_angles": snap}, Path("/"), gravity_parameter(Fraction(981, 100)),
                           unit_direction(SPATIAL_DOWN))
        if found is None:
            raise _fail(path, r.problems, (("arm.base_link", "--base"), ("arm.tip_link", "--tip")))
        return found

    found, snap = chain(), None
    if found.kept_angles and max(found.kept_angles) <= INIT_SNAP:   # pi/2 rounded by an exporter
        snap = snap_suggestion(found.kept_angles)
        found = chain(snap)
    return Source("urdf", path, described or shown, robot.name or "", "the URDF's robot name" if robot.name
                  else "the URDF file's name", base, tip, found, expanded=expanded, xacro=xacro, snap=snap)


def _mjcf(args, path: Path) -> Source:
    from derive.model.fields import Reader
    from derive.model.mjcf import gravity_in_base, mjcf_chain
    from derive.model.mjcf_xml import read_mjcf
    from derive.model.spec import gravity_parameter, unit_direction

    if getattr(args, "repair_inertia", False):
        raise DeriveError(f"--repair-inertia: expected a URDF, got the MJCF {path} (MuJoCo's compiler refuses a "
                          "non-physical inertia before derive reads it: correct the file's <inertial>)")
    r = Reader()
    doc = read_mjcf(r, "mjcf", str(path), Path.cwd(), "the path as given on the command line")
    if doc is None:
        raise _fail(path, r.problems)
    model = doc.model
    names = [model.body(b).name or f"(body {b})" for b in range(1, model.nbody)]   # as derive.model.mjcf names them
    parent = {names[b - 1]: names[int(model.body_parentid[b]) - 1] for b in range(1, model.nbody)
              if int(model.body_parentid[b]) != 0}
    base, tip = ends(parent, names, args.base, args.tip, "body")
    size, direction = gravity_in_base(model, base) if base in names else (9.81, (0.0, 0.0, -1.0))
    table = {"mjcf": str(path.resolve()), "base_body": base, "tip_body": tip}
    found = mjcf_chain(r, table, Path("/"), gravity_parameter(Fraction(repr(size))),
                       unit_direction(tuple(Fraction(repr(x)) for x in direction)))
    if found is None:
        raise _fail(path, r.problems, (("arm.base_body", "--base"), ("arm.tip_body", "--tip"),
                                       ("arm.mjcf", "mjcf")))
    robot = _model_name(model)
    return Source("mjcf", path, path.name, robot, "the MJCF's model name" if robot else "the MJCF file's name",
                  base, tip, found, size, direction, assumed_gravity=False)


def _model_name(model: Any) -> str:
    """``<mujoco model="...">`` ("" when absent or MuJoCo's default): the first name of the model's names."""
    text = bytes(model.names).split(b"\0")[0].decode("utf-8", "replace")
    return "" if text in ("", "MuJoCo Model") else text
