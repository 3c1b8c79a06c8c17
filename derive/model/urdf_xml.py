"""Reading a URDF file safely: size, hostile XML, numbers, then ``urdf_parser_py``.

Order: the file is read (at most 16 MiB); ``defusedxml`` parses it with
entity declarations and external references forbidden, so an
entity-expansion bomb or an external entity (``file:///etc/passwd``) is
refused before anything is expanded, and a DOCTYPE naming an external DTD is
refused too; every number in the elements the chain uses is checked (the
right count, finite) and a bad one named by its element and attribute; then
``urdf_parser_py`` (ROS's URDF parser; its lxml parser sees only checked
text) builds the robot. Messages the parser prints about unknown elements or
attributes become notes.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any
from xml.etree.ElementTree import Element, ParseError

from derive.model.fields import Reader, inline, show

MAX_URDF_BYTES = 16 << 20
# element path below <link> / <joint> -> its numeric attributes and their counts
_LINK_NUMBERS = {("inertial", "origin"): {"xyz": 3, "rpy": 3}, ("inertial", "mass"): {"value": 1},
                 ("inertial", "inertia"): {k: 1 for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}}
_JOINT_NUMBERS = {("origin",): {"xyz": 3, "rpy": 3}, ("axis",): {"xyz": 3},
                  ("limit",): {k: 1 for k in ("lower", "upper", "effort", "velocity")},
                  ("dynamics",): {"damping": 1, "friction": 1}, ("mimic",): {"multiplier": 1, "offset": 1}}
FIELD = "arm.urdf"


def _problem_in_numbers(text: str, count: int) -> str | None:
    parts = text.split()
    if len(parts) != count:
        return f"{count} number{'s' if count > 1 else ''} separated by spaces"
    for part in parts:
        try:
            x = float(part)
        except ValueError:
            return f"{count} number{'s' if count > 1 else ''} separated by spaces"
        if not math.isfinite(x):
            return f"{count} finite number{'s' if count > 1 else ''}"
    return None


def check_numbers(r: Reader, root: Element) -> None:
    """Every numeric attribute the chain reads: the right count of finite numbers."""
    for kind, table in (("link", _LINK_NUMBERS), ("joint", _JOINT_NUMBERS)):
        for element in root.findall(kind):
            name = element.get("name")
            for path, attrs in table.items():
                for node in element.findall("/".join(path)):
                    for attr, count in attrs.items():
                        text = node.get(attr)
                        if text is None:
                            continue
                        why = _problem_in_numbers(text, count)
                        if why is not None:
                            where = "".join(f"<{p}>" for p in path[:-1]) + f"<{path[-1]} {attr}>"
                            r.add(f"urdf {kind} {name!r} {where}", why, repr(text) if len(text) <= 60
                                  else repr(text[:60]) + "...")


def _read(r: Reader, value: Any, base_dir: Path) -> bytes | None:
    if not isinstance(value, str) or not value:
        r.bad(FIELD, "the path of a URDF file (relative to the arm file)", value)
        return None
    path = base_dir / value
    try:
        with open(path, "rb") as stream:
            raw = stream.read(MAX_URDF_BYTES + 1)
    except FileNotFoundError:
        r.add(FIELD, "a readable URDF file (path relative to the arm file)", f"{show(value)} (no such file: {path})")
        return None
    except (OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        r.add(FIELD, "a readable URDF file (path relative to the arm file)", f"{show(value)} ({why})")
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
        r.add(FIELD, "well-formed XML (a URDF)", str(exc))
        return None
    except ValueError as exc:   # e.g. an encoding the parser does not know
        r.add(FIELD, "well-formed XML (a URDF)", str(exc))
        return None
    if root.tag != "robot":
        r.add(FIELD, "a URDF: an XML document whose root element is <robot>", f"<{inline(root.tag)}>")
        return None
    return root


def parse_safely(r: Reader, value: Any, base_dir: Path, notes: list[str]) -> Any | None:
    """The ``urdf_parser_py`` robot of the file ``value`` names, or None after adding problems."""
    raw = _read(r, value, base_dir)
    if raw is None:
        return None
    root = _safe_tree(r, raw)
    if root is None:
        return None
    check_numbers(r, root)
    if r.problems:
        return None
    import urdf_parser_py.xml_reflection.core as core
    from urdf_parser_py.urdf import URDF

    said: list[str] = []
    previous = core.on_error
    core.on_error = said.append
    try:
        robot = URDF.from_xml_string(raw)
    except Exception as exc:  # noqa: BLE001 - the parser raises ParseError, ValueError, AssertionError, ...
        first = str(exc).strip().splitlines()
        r.add(FIELD, "a URDF that urdf_parser_py reads", f"{type(exc).__name__}: {' '.join(first)[:200]}")
        return None
    finally:
        core.on_error = previous
    for text in said[:5]:
        notes.append(f"ignored by the URDF parser: {' '.join(text.split())}")
    if len(said) > 5:
        notes.append(f"ignored by the URDF parser: {len(said) - 5} more such elements or attributes")
    return robot
