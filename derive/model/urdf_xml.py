"""Reading a URDF file safely: size, hostile XML, what derive reads, numbers, then ``urdf_parser_py``.

Order: the file is read (at most 16 MiB); ``defusedxml`` parses it with
entity declarations and external references forbidden, so an
entity-expansion bomb or an external entity (``file:///etc/passwd``) is
refused before anything is expanded, and a DOCTYPE naming an external DTD is
refused too. Then the document is cut down to what derive reads
(:data:`READ`: each link's ``<inertial>``, each joint's origin, parent, child,
axis, limit, dynamics and mimic): transmissions, Gazebo tags, sensors,
materials, visual and collision geometry (meshes) are dropped unread, so a
value in them that no parser could read (xArm6's unexpanded xacro
``<mechanicalReduction>reduction</mechanicalReduction>``) never blocks, and
one note counts what was dropped. An unknown element or attribute inside a
read element is recorded as a :class:`Finding` (``dynamics`` when it sits
where it may change the dynamics: ``<inertial>``, a joint's ``<origin>``,
``<axis>``, ``<dynamics>``, ``<mimic>``; e.g. ``<dynamics><damping>100</damping>``,
a child element that URDF does not define). An element URDF defines once
given more than once (two ``<mass>``: urdf_parser_py would keep the first and
only say "Scalar element defined multiple times") is a Finding naming its link
or joint and element; the first is read. Every number of the read
elements is checked (the right count, finite); a bad one becomes a Finding
naming its element and attribute and is replaced by zeros in what the parser
sees. Whether a Finding is an error, a warning or a note is decided by
:mod:`derive.model.urdf`, which knows the chain: strict where the element
moves with the chain, a note elsewhere. Then ``urdf_parser_py`` (ROS's URDF
parser; its lxml parser sees only the checked, cut-down text) builds the
robot; whatever it still says is a Finding of the link or joint its message
names (an error on the chain, a warning off it). Messages are shortened only at word boundaries (:func:`clip`).
"""
from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree.ElementTree import Element, ParseError, SubElement, tostring

from derive.errors import Problem
from derive.model.fields import Reader, inline, show

MAX_URDF_BYTES = 16 << 20
INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
# element path below <robot> -> {attribute read: how many numbers it holds (0: a name)}, children read
READ: dict[tuple[str, ...], tuple[dict[str, int], tuple[str, ...]]] = {
    ("link",): ({"name": 0}, ("inertial",)),
    ("link", "inertial"): ({}, ("origin", "mass", "inertia")),
    ("link", "inertial", "origin"): ({"xyz": 3, "rpy": 3}, ()),
    ("link", "inertial", "mass"): ({"value": 1}, ()),
    ("link", "inertial", "inertia"): ({k: 1 for k in INERTIA_KEYS}, ()),
    ("joint",): ({"name": 0, "type": 0}, ("origin", "parent", "child", "axis", "limit", "dynamics", "mimic")),
    ("joint", "origin"): ({"xyz": 3, "rpy": 3}, ()),
    ("joint", "parent"): ({"link": 0}, ()),
    ("joint", "child"): ({"link": 0}, ()),
    ("joint", "axis"): ({"xyz": 3}, ()),
    ("joint", "limit"): ({k: 1 for k in ("lower", "upper", "effort", "velocity")}, ()),
    ("joint", "dynamics"): ({"damping": 1, "friction": 1}, ()),
    ("joint", "mimic"): ({"joint": 0, "multiplier": 1, "offset": 1}, ()),
}
# URDF elements derive does not need (they never change the rigid-body dynamics)
UNREAD = {("link",): ("visual", "collision"), ("joint",): ("calibration", "safety_controller")}
# where an unknown element or attribute may change the dynamics (a warning when on the chain)
DYNAMICS = {("link", "inertial"), ("link", "inertial", "origin"), ("link", "inertial", "mass"),
            ("link", "inertial", "inertia"), ("joint", "origin"), ("joint", "axis"), ("joint", "dynamics"),
            ("joint", "mimic")}
FIELD = "arm.urdf"


def clip(text: str, limit: int = 300) -> str:
    """``text`` on one line, shortened to at most about ``limit`` characters at a word
    boundary (never inside a word), with the count of what was left out."""
    text = " ".join(text.split())
    if len(text) <= limit:
        return text
    cut = text.rfind(" ", 0, limit)
    if cut <= 0:
        return f"a word of {len(text)} characters"
    return f"{text[:cut]} ... ({len(text) - cut} more characters)"


@dataclass(frozen=True)
class Finding:
    """Something in the URDF derive did not use as written: a bad number (``number``) or
    an unknown element or attribute, or an element URDF defines once given more than once
    (``twice``, with ``number``: strict on the chain, a warning off it). ``kind``, ``name``: the
    link or joint it belongs to; ``dynamics``: it sits where it may change the dynamics."""

    kind: str
    name: str
    problem: Problem
    number: bool = False
    dynamics: bool = False
    twice: bool = False


@dataclass
class UrdfDocument:
    """A URDF read by :func:`parse_safely`: the ``urdf_parser_py`` robot of what derive
    reads, the notes (what was dropped unread), and the findings for the caller to judge."""

    robot: Any
    notes: list[str] = field(default_factory=list)
    findings: list[Finding] = field(default_factory=list)


def _problem_in_numbers(text: str, count: int) -> str | None:
    what = f"{count} numbers separated by spaces" if count > 1 else "a number"
    parts = text.split()
    if len(parts) != count:
        return what
    for part in parts:
        try:
            x = float(part)
        except ValueError:
            return what
        if not math.isfinite(x):
            return f"{count} finite numbers" if count > 1 else "a finite number"
    return None


def _where(path: tuple[str, ...], attr: str | None = None) -> str:
    inner = path[1:]
    if not inner:
        return f"<{path[0]} {attr}>" if attr else ""
    return "".join(f"<{p}>" for p in inner[:-1]) + (f"<{inner[-1]} {attr}>" if attr else f"<{inner[-1]}>")


def _given(text: str) -> str:
    shown = clip(text, 60)
    return repr(shown) if shown == " ".join(text.split()) else shown


def cut_down(root: Element) -> tuple[Element, list[str], list[Finding]]:
    """The part of ``root`` that derive reads (a new tree; numbers checked, bad ones
    replaced by zeros), a note counting what was dropped, and the findings."""
    out = Element("robot", {"name": root.get("name", "")})   # a robot without a name is read (the name: "")
    dropped: Counter[str] = Counter()
    findings: list[Finding] = []

    def copy(source: Element, target: Element, path: tuple[str, ...], owner: tuple[str, str]) -> None:
        attrs, children = READ[path]
        unknown = [f"{attr}={_given(text)}" for attr, text in source.attrib.items() if attr not in attrs]
        if unknown:
            findings.append(Finding(*owner, Problem(f"urdf {owner[0]} {owner[1]!r} {_where(path)}".rstrip(),
                            f"the attributes URDF defines there ({', '.join(attrs) or 'none'})",
                            f"also {', '.join(unknown)}, not read"), dynamics=path in DYNAMICS))
        for attr, text in source.attrib.items():
            if attr not in attrs:
                continue
            count = attrs[attr]
            why = _problem_in_numbers(text, count) if count else None
            if why is not None:
                findings.append(Finding(*owner, Problem(f"urdf {owner[0]} {owner[1]!r} {_where(path, attr)}", why,
                                                        _given(text)), number=True))
                text = " ".join(["0"] * count)
            target.set(attr, text)
        seen: Counter[str] = Counter(c.tag for c in source if isinstance(c.tag, str) and c.tag in children)
        for tag, count in seen.items():
            if count > 1:   # URDF defines each of these once; urdf_parser_py would keep the first silently
                findings.append(Finding(*owner, Problem(f"urdf {owner[0]} {owner[1]!r} {_where(path + (tag,))}",
                                                        f"one <{tag}>", f"{count}"), number=True, twice=True))
        for child in source:
            if not isinstance(child.tag, str):
                continue
            if child.tag in children:
                if seen[child.tag] > 1 and target.find(child.tag) is not None:
                    continue   # the first is read; the repetition is a finding above
                copy(child, SubElement(target, child.tag), path + (child.tag,), owner)
            elif child.tag in UNREAD.get(path, ()):
                dropped[f"<{child.tag}>"] += 1
            else:
                content = clip(" ".join(child.itertext()), 60)
                findings.append(Finding(*owner, Problem(
                    f"urdf {owner[0]} {owner[1]!r} {_where(path + (child.tag,))}",
                    f"only the elements URDF defines inside <{path[-1]}> ({', '.join(children) or 'none'}; "
                    + (f"<{path[-1]}> takes {', '.join(attrs)} as attributes" if attrs else "") + ")",
                    f"an element <{child.tag}>{content}</{child.tag}>, not read"), dynamics=path in DYNAMICS))

    for element in root:
        if not isinstance(element.tag, str):
            continue
        if element.tag in ("link", "joint"):
            copy(element, SubElement(out, element.tag), (element.tag,), (element.tag, element.get("name", "")))
        else:
            dropped[f"<{element.tag}>"] += 1
    notes = []
    if dropped:
        counts = ", ".join(f"{n} {tag}" for tag, n in sorted(dropped.items(), key=lambda x: (-x[1], x[0])))
        notes.append(f"not read (they do not change the rigid-body dynamics): {counts}")
    return out, notes, findings


def _read(r: Reader, value: Any, base_dir: Path, whence: str) -> bytes | None:
    if not isinstance(value, str) or not value:
        r.bad(FIELD, f"the path of a URDF file ({whence})", value)
        return None
    path = base_dir / value
    try:
        with open(path, "rb") as stream:
            raw = stream.read(MAX_URDF_BYTES + 1)
    except FileNotFoundError:
        r.add(FIELD, f"a readable URDF file ({whence})", f"{show(value)} (no such file: {path})")
        return None
    except (OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        r.add(FIELD, f"a readable URDF file ({whence})", f"{show(value)} ({why})")
        return None
    if len(raw) > MAX_URDF_BYTES:
        r.add(FIELD, f"a URDF file of at most {MAX_URDF_BYTES} bytes", f"{show(value)} (a larger file)")
        return None
    return raw


def _safe_tree(r: Reader, raw: bytes) -> Element | None:
    """The document parsed by defusedxml, or None (problem added) when hostile or malformed."""
    import defusedxml.ElementTree as safe
    from defusedxml import DTDForbidden, EntitiesForbidden, ExternalReferenceForbidden

    try:
        root = safe.fromstring(raw, forbid_dtd=False, forbid_entities=True, forbid_external=True)
        safe.fromstring(raw, forbid_dtd=True)
    except EntitiesForbidden as exc:
        if exc.sysid or exc.pubid:
            r.add(FIELD, "XML without external entities (refused unread)",
                  f"an external entity {exc.name!r} -> {inline(exc.sysid or exc.pubid)}")
        else:
            r.add(FIELD, "XML without entity declarations (a URDF needs none; refused unexpanded: "
                  "entity expansion can take unbounded memory)", f"an entity declaration {exc.name!r}")
        return None
    except ExternalReferenceForbidden as exc:
        r.add(FIELD, "XML without external references (refused unread)", f"a reference to {inline(exc.sysid)}")
        return None
    except DTDForbidden as exc:
        if exc.sysid or exc.pubid:
            r.add(FIELD, "XML without an external DTD (refused unread)",
                  f"<!DOCTYPE {exc.name} ...> naming {inline(exc.sysid or exc.pubid)}")
            return None
        root = safe.fromstring(raw, forbid_dtd=False, forbid_entities=True, forbid_external=True)
    except ParseError as exc:
        r.add(FIELD, "well-formed XML (a URDF)", clip(str(exc)))
        return None
    except ValueError as exc:   # e.g. an encoding the parser does not know
        r.add(FIELD, "well-formed XML (a URDF)", clip(str(exc)))
        return None
    if root.tag != "robot":
        r.add(FIELD, "a URDF: an XML document whose root element is <robot>", f"<{inline(root.tag)}>")
        return None
    return root


def parse_safely(r: Reader, value: Any, base_dir: Path,
                 whence: str = "path relative to the arm file") -> UrdfDocument | None:
    """The URDF file ``value`` names (relative to ``base_dir``) read as described in the
    module docstring, or None after adding problems (file, XML, parser) to ``r``; ``whence``
    says in those messages where the path is from."""
    raw = _read(r, value, base_dir, whence)
    if raw is None:
        return None
    root = _safe_tree(r, raw)
    if root is None:
        return None
    tree, notes, findings = cut_down(root)
    import urdf_parser_py.xml_reflection.core as core
    from urdf_parser_py.urdf import URDF

    said: list[str] = []
    previous = core.on_error
    core.on_error = said.append
    try:
        robot = URDF.from_xml_string(tostring(tree))
    except Exception as exc:  # noqa: BLE001 - the parser raises ParseError, ValueError, AssertionError, ...
        r.add(FIELD, "a URDF that urdf_parser_py reads", clip(f"{type(exc).__name__}: {exc}"))
        return None
    finally:
        core.on_error = previous
    return UrdfDocument(robot, notes, findings + [_parser_finding(text) for text in said])


_OWNER = re.compile(r" in /robot(?:\[@name='[^']*'\])?/(link|joint)\[@name='([^']*)'\](\S*)\Z")


def _parser_finding(text: str) -> Finding:
    """What urdf_parser_py said (it reads on after it) as a Finding judged like an element given
    twice: an error when its link or joint matters, else a warning; one its message does not place
    under a link or joint is owned by the robot (a warning: no link or joint of the chain)."""
    m = _OWNER.search(text)
    kind, name, rest = m.groups() if m else ("robot", "", "")
    where = "".join(f"<{tag}>" for tag in rest.split("/") if tag)
    field = f"urdf {kind} {name!r} {where}".rstrip() if m else FIELD
    return Finding(kind, name, Problem(field, "a URDF that urdf_parser_py reads without a complaint",
                                       f"it said: {clip(text)}"), number=True, twice=True)
