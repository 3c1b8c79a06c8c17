"""The file MuJoCo integrates, read safely and stripped to what the dynamics need.

Which file: ``[simulation] mujoco_model`` (an MJCF, or a URDF, relative to the arm file)
when the arm file names one, else the arm's own URDF or MJCF (``[arm] urdf``, ``[arm] mjcf``).
A planar or DH arm has no such file: it needs ``mujoco_model``.

Reading: at most 16 MiB; ``defusedxml`` parses the text first with DTDs, entity
declarations and external references forbidden (an entity bomb or ``file:///etc/passwd``
is refused unexpanded), so MuJoCo's own parser sees only checked text.

Stripping (MuJoCo then needs no mesh file):

* URDF: every ``<visual>`` and ``<collision>`` (MuJoCo integrates the ``<inertial>``
  data only; a link without one is massless, as derive reads it), ``<transmission>``,
  ``<gazebo>`` and any ``<mujoco>`` block are removed; joint ``<limit lower upper>`` are
  removed (derive's plant has no joint limits, neither has MuJoCo's); an ``rpy`` angle
  within 1e-9 rad of a multiple of pi/2 is written as that multiple to the last bit, as
  derive reads it (derive.model.rigid: ROS writes pi/2 as 1.57079632679, 4.9e-12 rad off),
  so that both plants integrate the same kinematics; the inertia of each link derive repaired
  (``repair_inertia``) is the repaired tensor; a link whose inertia is not physical and that derive
  does not use (it does not move with the chain) loses its ``<inertial>`` (MuJoCo's compiler
  would refuse it; the link stays fixed); one
  ``<mujoco><compiler>`` block is added: no inertia from geometry, no inertia
  balancing, static bodies kept apart until derive has applied its mismatch
  (:mod:`.model` fuses them when it compiles).
* MJCF: its ``<include>`` files expanded in place (derive.model.mjcf_xml: each read safely,
  relative to the main file's folder), otherwise kept as written here; :mod:`.model` removes
  its mesh geoms and assets in the model it builds.

What derive holds goes with the source: ``locked`` (every joint of the file derive holds, with
its value: ``locked``'s, a URDF mimic's rule, else 0) and ``base`` (the link or body the chain
starts from: joints above it do not move in derive, so they are fixed in MuJoCo too).

The result is plain data (:class:`MujocoSource`): sweeps ship it to their workers.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from derive.errors import DeriveError
from derive.model.rigid import SNAP_TOLERANCE

MAX_BYTES = 16 << 20
COMPILER = {"discardvisual": "true", "fusestatic": "false", "balanceinertia": "false",
            "inertiafromgeom": "false", "strippath": "false"}


@dataclass(frozen=True)
class MujocoSource:
    """The model file of a MuJoCo plant: ``field`` (the arm-file key naming it), ``shown``
    (the path as written there), ``kind`` ("urdf" or "mjcf"), ``xml`` (the stripped text
    MuJoCo parses), ``folder`` (the file's folder), ``base`` (the URDF link or MJCF
    body derive's chain starts from, when the arm file names one), ``locked`` (joint -> value [rad or m]
    held: the arm file's ``locked``, and every other joint derive holds, at its value), ``notes``
    (what stripping removed), ``own`` (the file is the arm's own ``[arm] urdf`` or ``mjcf``: derive's
    chain was read from it), ``tip`` (the arm file's ``tip_link`` or ``tip_body``: the body a payload is
    welded to)."""

    field: str
    shown: str
    kind: str
    xml: str
    folder: str
    base: str | None
    locked: tuple[tuple[str, float], ...]
    notes: tuple[str, ...]
    own: bool = False
    tip: str | None = None   # the arm file's tip_link or tip_body (a payload is welded to it, derive.sim.mujoco.payload)


def _arm_table(arm) -> dict:
    """The ``[arm]`` table of the arm file (already validated by derive.model.spec)."""
    source = Path(arm.source)
    if arm.source.startswith("<") or not source.is_file():
        return {}
    try:
        data = tomllib.loads(source.read_bytes().decode("utf-8-sig"))
    except (OSError, ValueError):
        return {}
    table = data.get("arm", {})
    return table if isinstance(table, dict) else {}


def _read(field: str, shown: str, path: Path) -> bytes:
    try:
        with open(path, "rb") as stream:
            raw = stream.read(MAX_BYTES + 1)
    except FileNotFoundError:
        raise DeriveError(f"{field}: expected a readable MJCF or URDF file (path relative to the arm file), "
                          f"got {shown!r} (no such file: {path})") from None
    except (OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        raise DeriveError(f"{field}: expected a readable MJCF or URDF file, got {shown!r} ({why})") from None
    if len(raw) > MAX_BYTES:
        raise DeriveError(f"{field}: expected a model file of at most {MAX_BYTES} bytes, got {shown!r} (larger)")
    return raw


def _tree(field: str, shown: str, raw: bytes):
    """The document parsed by defusedxml (no DTD, no entities, no external references)."""
    import defusedxml.ElementTree as safe
    from defusedxml import DefusedXmlException
    from xml.etree.ElementTree import ParseError

    try:
        return safe.fromstring(raw, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException as exc:
        raise DeriveError(f"{field}: expected XML without a DTD, entity declarations or external references "
                          f"(refused unexpanded), got {shown!r}: {exc}") from None
    except (ParseError, ValueError) as exc:
        raise DeriveError(f"{field}: expected well-formed XML (an MJCF or a URDF), got {shown!r}: {exc}") from None


def _strip_urdf(root, repaired: dict[str, tuple] | None = None, tolerance: float = SNAP_TOLERANCE) -> list[str]:
    """Remove what MuJoCo does not need from a URDF tree (module docstring); say what. ``repaired``:
    link -> the six entries (ixx, ixy, ixz, iyy, iyz, izz) derive repaired it to; ``tolerance``: the
    arm's snapping tolerance (``[arm] snap_angles``, derive.model.rigid.snapping)."""
    from xml.etree.ElementTree import SubElement

    removed: dict[str, int] = {}

    def drop(parent, tag: str) -> None:
        for child in parent.findall(tag):
            parent.remove(child)
            removed[tag] = removed.get(tag, 0) + 1

    for link in root.findall("link"):
        drop(link, "visual")
        drop(link, "collision")
    for tag in ("transmission", "gazebo", "mujoco"):
        drop(root, tag)
    for limit in root.findall("joint/limit"):
        for key in ("lower", "upper"):
            limit.attrib.pop(key, None)
    snapped = _snap_angles(root, tolerance)
    inertias = _inertias(root, repaired or {})
    SubElement(SubElement(root, "mujoco"), "compiler", COMPILER)
    notes = [f"rpy angles within {tolerance:g} rad of a multiple of pi/2 given to MuJoCo as that multiple, as "
             f"derive reads them (derive.model.rigid): {snapped}"] if snapped else []
    notes += inertias
    if not removed:
        return notes
    return ["removed from the URDF before MuJoCo read it: "
            + ", ".join(f"{k} <{tag}>" for tag, k in removed.items())
            + " (MuJoCo integrates the <inertial> data; no mesh file is read)", *notes]


def _inertias(root, repaired: dict[str, tuple]) -> list[str]:
    """The repaired tensors written into their links; the <inertial> of a link whose tensor is not
    physical and not repaired removed (derive refused it if it moved with the chain, so it does not);
    what was done, as notes."""
    from fractions import Fraction

    import sympy as sp

    from derive.model.rigid import inertia_problem

    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    index = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
    written, dropped = [], []
    for link in root.findall("link"):
        name, inertial = link.get("name", ""), link.find("inertial")
        tensor = None if inertial is None else inertial.find("inertia")
        if tensor is None:
            continue
        if name in repaired:
            for key, x in zip(keys, repaired[name]):
                tensor.set(key, repr(float(x)))
            written.append(repr(name))
            continue
        try:
            e = [Fraction(tensor.get(k, "0").strip() or "0") for k in keys]
        except (ValueError, ZeroDivisionError):
            continue    # derive's reader has its own message for it
        I = sp.Matrix(3, 3, lambda i, j: sp.Rational(e[index.index((min(i, j), max(i, j)))]))
        if inertia_problem(I) is not None:
            link.remove(inertial)
            dropped.append(repr(name))
    notes = [f"inertias as derive repaired them (repair_inertia): {', '.join(written)}"] if written else []
    if dropped:
        notes.append(f"<inertial> removed from links derive does not use whose inertia is not physical (MuJoCo would "
                     f"refuse it): {', '.join(dropped)}")
    return notes


def _snap_angles(root, tolerance: float = SNAP_TOLERANCE) -> str:
    """Write every ``<origin rpy>`` angle of the joints and inertials that derive snaps to a
    multiple k pi/2 (derive.model.rigid.exact_angle: within ``tolerance``) as k pi/2 in double;
    return what changed ("" when nothing), e.g. "1.57079632679 -> pi/2 (4 times)"."""
    changed: dict[str, int] = {}
    for origin in [*root.findall("joint/origin"), *root.findall("link/inertial/origin")]:
        text = origin.get("rpy")
        try:
            values = [float(x) for x in (text or "").split()]
        except ValueError:
            continue   # derive's reader has its own message for it (or does not read this element)
        out = []
        for x in values:
            k = round(x / (math.pi / 2))
            off = abs(x - k * math.pi / 2)
            if 0.0 < off <= tolerance:
                target = {0: "0", 1: "pi/2", -1: "-pi/2", 2: "pi", -2: "-pi"}.get(k, f"{k}*pi/2")
                changed[f"{x!r} -> {target}"] = changed.get(f"{x!r} -> {target}", 0) + 1
                x = k * (math.pi / 2)
            out.append(repr(x))
        if len(out) == 3 and any(f"{x!r}" != y for x, y in zip(values, out)):
            origin.set("rpy", " ".join(out))
    return ", ".join(f"{what} ({k} time{'s' if k > 1 else ''})" for what, k in changed.items())


def load_source(arm) -> MujocoSource:
    """The MuJoCo model file of ``arm`` (module docstring); DeriveError naming the arm-file
    field when there is none, it is missing, unreadable, hostile or not an MJCF/URDF."""
    table = _arm_table(arm)
    folder = Path(arm.source).parent if not arm.source.startswith("<") else Path.cwd()
    if arm.simulation.mujoco_model:
        field, shown = "simulation.mujoco_model", arm.simulation.mujoco_model
    elif isinstance(table.get("urdf"), str) or isinstance(table.get("mjcf"), str):
        field = "arm.urdf" if isinstance(table.get("urdf"), str) else "arm.mjcf"
        shown = table[field.split(".")[1]]
    else:
        kind = "a URDF or MJCF arm whose file derive cannot re-read" if arm.spatial is not None else \
            "a planar [[link]] or DH arm (no URDF or MJCF)"
        raise DeriveError(f"--plant mujoco: expected the arm's URDF or MJCF ([arm] urdf, [arm] mjcf) or a model file "
                          f"named by [simulation] mujoco_model = \"arm.xml\" (an MJCF or URDF, relative to the arm "
                          f"file), got {kind} without mujoco_model")
    path = folder / shown
    root = _tree(field, shown, _read(field, shown, path))
    chain = arm.spatial
    repaired = dict(chain.repaired) if chain is not None else {}
    if root.tag == "robot":
        snap = table.get("snap_angles")   # validated by derive.model.urdf.snap_choice
        notes = _strip_urdf(root, repaired, SNAP_TOLERANCE if snap is None else float(snap))
        kind = "urdf"
    elif root.tag == "mujoco":
        if next(root.iter("include"), None) is not None:
            from derive.model.fields import Reader
            from derive.model.mjcf_xml import expanded_tree

            r = Reader()
            root, _ = expanded_tree(r, field, shown, folder, "path relative to the arm file")
            if root is None:
                raise DeriveError(str(r.problems[0]))
        notes, kind = [], "mjcf"
    else:
        raise DeriveError(f"{field}: expected an MJCF (root element <mujoco>) or a URDF (<robot>), got {shown!r} "
                          f"with root element <{root.tag}>")
    from xml.etree.ElementTree import tostring

    from derive.model.fields import to_fraction

    locked = {str(k): to_fraction(v) for k, v in (table.get("locked") or {}).items()} \
        if isinstance(table.get("locked"), dict) else {}   # validated by derive.model.urdf / mjcf
    held = {name: float(v) for name, v in locked.items() if v is not None}
    if chain is not None:
        held.update(dict(chain.held))
    key = "base_link" if kind == "urdf" else "base_body"
    base = table.get(key) if field in ("arm.urdf", "arm.mjcf") or kind == "urdf" else None
    return MujocoSource(field=field, shown=shown, kind=kind, xml=tostring(root, encoding="unicode"),
                        folder=str(path.parent.resolve()), base=base if isinstance(base, str) else None,
                        locked=tuple(sorted(held.items())), notes=tuple(notes),
                        own=field in ("arm.urdf", "arm.mjcf"), tip=_tip_name(table))


def _tip_name(table: dict) -> str | None:
    """The arm file's tip link (URDF) or tip body (MJCF), None when it names neither."""
    tip = table.get("tip_link", table.get("tip_body"))
    return tip if isinstance(tip, str) else None
