"""Reading an MJCF file safely, and compiling it with MuJoCo's own compiler.

Order: the file and every file it ``<include>``\\ s (resolved as MuJoCo does, relative to the
main file's folder; at most ``MAX_INCLUDES`` files, each at most 16 MiB, no cycle) are read and
parsed by ``defusedxml`` with DTDs, entity declarations and external references forbidden, so
an entity bomb or ``file:///etc/passwd`` is refused unexpanded; a missing include is one error
naming its ``<include file>``. The includes are expanded in place (MuJoCo's rule: the children
of the included file's ``<mujoco>`` root replace the ``<include>`` element), and MuJoCo's parser
(``mujoco.MjSpec.from_string``) reads the one expanded text. Then the geometry that needs files
goes (mesh, height-field and SDF geoms; mesh, height-field, texture, material and skin assets):
no file but the model's is read, and a body whose mass and inertia MuJoCo would compute from such
a geom is an error (give it an ``<inertial>``); a body whose inertia comes from primitive geoms
(boxes, capsules, ...) keeps it, computed by MuJoCo's compiler. MuJoCo compiles the rest with
static bodies kept apart (``fusestatic`` off, so every body keeps its name): the compiled
``MjModel`` gives every body's frame, inertia and joint in canonical form (frames in
``pos``/``quat``/``euler``/``axisangle``/``xyaxes``/``zaxis``, the compiler's ``angle`` and
``eulerseq``, ``<default>`` classes and ``<frame>`` elements all resolved by MuJoCo).

``mujoco`` is an optional dependency (``pip install 'derive[mujoco]'``); an MJCF arm needs it.
"""
from __future__ import annotations

import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree.ElementTree import Element, ParseError, tostring

from derive.model.fields import Reader, show
from derive.model.urdf_xml import clip

MAX_BYTES = 16 << 20
MAX_INCLUDES = 64
INSTALL = "pip install 'derive[mujoco]'"
SHAPED = ("mjGEOM_MESH", "mjGEOM_HFIELD", "mjGEOM_SDF")
FILE_ASSETS = ("meshes", "hfields", "textures", "materials", "skins")


def require_mujoco(r: Reader, field: str) -> Any:
    """The ``mujoco`` module, or None after adding a problem with the install command."""
    try:
        import mujoco
    except ImportError as exc:
        r.add(field, f"the mujoco package to read an MJCF (MuJoCo's Python bindings; install it with {INSTALL})",
              f"{type(exc).__name__}: {exc}")
        return None
    return mujoco


@contextmanager
def collected_warnings(mj: Any):
    """MuJoCo's warnings while parsing and compiling, collected in the yielded list (its default
    handler would print them and write MUJOCO_LOG.TXT into the working folder; its compiler raises
    Python warnings), the previous handler restored."""
    said: list[str] = []
    previous = mj.get_mju_user_warning()
    mj.set_mju_user_warning(said.append)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield said
        said.extend(str(w.message) for w in caught)
    finally:
        mj.set_mju_user_warning(previous)


@dataclass
class MjcfDocument:
    """An MJCF read by :func:`read_mjcf`: MuJoCo's ``spec`` (geometry that needs files removed) and
    its compiled ``model``, the expanded ``xml`` text, the ``files`` read, and what was removed."""

    spec: Any
    model: Any
    xml: str
    files: tuple[Path, ...]
    notes: list[str] = field(default_factory=list)


def _read(path: Path) -> tuple[bytes | None, str]:
    try:
        with open(path, "rb") as stream:
            raw = stream.read(MAX_BYTES + 1)
    except FileNotFoundError:
        return None, f"no such file: {path}"
    except (OSError, ValueError) as exc:
        return None, getattr(exc, "strerror", None) or str(exc)
    if len(raw) > MAX_BYTES:
        return None, f"a file larger than {MAX_BYTES} bytes"
    return raw, ""


def _safe(raw: bytes) -> tuple[Element | None, str]:
    import defusedxml.ElementTree as safe
    from defusedxml import DefusedXmlException

    try:
        return safe.fromstring(raw, forbid_dtd=True, forbid_entities=True, forbid_external=True), ""
    except DefusedXmlException as exc:
        return None, f"XML with a DTD, an entity declaration or an external reference (refused unexpanded: {exc})"
    except (ParseError, ValueError) as exc:
        return None, f"malformed XML: {clip(str(exc))}"


def expanded_tree(r: Reader, field: str, value: Any, base_dir: Path, whence: str) -> tuple[Element | None, list[Path]]:
    """The MJCF ``value`` names (relative to ``base_dir``) read safely with its includes expanded
    (module docstring), and the files read; None after adding one problem naming the file or the
    ``<include>``."""
    if not isinstance(value, str) or not value:
        r.bad(field, f"the path of an MJCF file ({whence})", value)
        return None, []
    main = Path(base_dir) / value
    raw, why = _read(main)
    if raw is None:
        r.add(field, f"a readable MJCF file ({whence})", f"{show(value)} ({why})")
        return None, []
    root, why = _safe(raw)
    if root is None:
        r.add(field, "well-formed XML without DTDs or entities (an MJCF)", f"{show(value)}: {why}")
        return None, []
    if root.tag != "mujoco":
        r.add(field, "an MJCF: an XML document whose root element is <mujoco>", f"{show(value)} with <{root.tag}>")
        return None, []
    files = [main]

    def expand(parent: Element, trail: tuple[Path, ...]) -> bool:
        for k, child in enumerate(list(parent)):
            if child.tag != "include":
                if isinstance(child.tag, str) and not expand(child, trail):
                    return False
                continue
            name = child.get("file")
            where = f"{field} <include file={name!r}> in {trail[-1].name}"
            target = main.parent / name if name else None
            if target is None or len(files) >= MAX_INCLUDES or target.resolve() in {t.resolve() for t in trail}:
                given = ("no file attribute" if target is None else f"more than {MAX_INCLUDES} files"
                         if len(files) >= MAX_INCLUDES else "a file that includes itself (an include cycle)")
                r.add(where, "an included MJCF file (path relative to the main file's folder)", given)
                return False
            data, why = _read(target)
            sub, why = (None, why) if data is None else _safe(data)
            if sub is None or sub.tag != "mujoco":
                r.add(where, "a readable MJCF file whose root element is <mujoco> (path relative to the main "
                      "file's folder, as MuJoCo resolves it)", why or f"root element <{sub.tag}>")
                return False
            files.append(target)
            if not expand(sub, trail + (target,)):
                return False
            parent.remove(child)
            for offset, inner in enumerate(list(sub)):
                parent.insert(k + offset, inner)
            return expand(parent, trail)   # the inserted children may hold includes of their own
        return True

    if not expand(root, (main,)):
        return None, files
    return root, files


def strip_file_geometry(mj: Any, spec: Any) -> tuple[dict[str, int], list[tuple[str, str, str]]]:
    """Remove mesh, height-field and SDF geoms and the assets that need files (module docstring).
    Returns what was removed (counts) and, for each body whose inertia MuJoCo would compute from
    such a geom, (body name, geom kind, geom name): the caller's error."""
    from_geoms = spec.compiler.inertiafromgeom
    shaped = tuple(getattr(mj.mjtGeom, k) for k in SHAPED)
    geoms = [g for g in spec.geoms if g.type in shaped]
    inferred = []
    for g in geoms:
        body = g.parent
        if from_geoms == mj.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE or (
                from_geoms == mj.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO and not body.explicitinertial):
            inferred.append((body.name or "(unnamed)", str(g.type).split("_")[-1].lower(), g.name or "(unnamed)"))
    for g in spec.geoms:
        g.material = ""
    for g in geoms:
        spec.delete(g)
    removed = {"mesh geoms": len(geoms)} if geoms else {}
    for kind in FILE_ASSETS:
        items = list(getattr(spec, kind))
        for item in items:
            spec.delete(item)
        if items and kind in ("meshes", "hfields"):
            removed[kind] = len(items)
    return removed, inferred


MINVAL = "mass and inertia of moving bodies must be larger than mjMINVAL"


def compile_error(text: str) -> tuple[str, str]:
    """MuJoCo's compiler message as (the element it names, what it says), one line each."""
    lines = [x.strip() for x in str(text).splitlines() if x.strip()]
    element = next((x for x in lines if x.startswith("Element")), "")
    said = " ".join(x for x in lines if not x.startswith("Element"))
    return element, said.removeprefix("Error: ")


def read_mjcf(r: Reader, field: str, value: Any, base_dir: Path,
              whence: str = "path relative to the arm file") -> MjcfDocument | None:
    """The MJCF file ``value`` names (relative to ``base_dir``), read, parsed and compiled as the module
    docstring says, or None after adding one problem to ``r`` naming ``field`` and the element."""
    mj = require_mujoco(r, field)
    if mj is None:
        return None
    root, files = expanded_tree(r, field, value, base_dir, whence)
    if root is None:
        return None
    xml = tostring(root, encoding="unicode")
    with collected_warnings(mj) as said:
        try:
            spec = mj.MjSpec.from_string(xml)
        except Exception as exc:  # noqa: BLE001 - MuJoCo's parser raises ValueError with its own message
            r.add(field, "an MJCF that MuJoCo's parser reads", clip(" ".join(str(exc).split())))
            return None
        spec.modelfiledir = str(files[0].parent.resolve())
        spec.compiler.fusestatic = False
        removed, inferred = strip_file_geometry(mj, spec)
        if inferred:
            body, kind, geom = inferred[0]
            r.add(f"{field} body {body!r}", "an <inertial> (mass and inertia) on every body that has one; derive "
                  "does not read mesh files, and refuses mass and inertia MuJoCo would compute from a mesh",
                  f"none: MuJoCo would compute them from its {kind} geom {geom!r}"
                  + (f" (and {len(inferred) - 1} more such bodies)" if len(inferred) > 1 else ""))
            return None
        try:
            model = spec.compile()
        except Exception as exc:  # noqa: BLE001 - MuJoCo's compiler raises ValueError with its own message
            element, text = compile_error(str(exc))
            name = element.split("'")[1] if element.count("'") >= 2 else ""
            if MINVAL in text:
                r.add(f"{field} body {name!r}", "mass and inertia on every body a joint moves (an <inertial>, or "
                      "primitive geoms MuJoCo computes them from)", "none (MuJoCo: " + text + ")")
            else:
                r.add(f"{field}" + (f" body {name!r}" if "body" in element.lower() or name else ""),
                      "an MJCF that MuJoCo's compiler compiles", clip(f"{text} ({element})" if element else text))
            return None
    notes = []
    if removed:
        notes.append("not read (derive reads no mesh file): " + ", ".join(f"{k} {what}" for what, k in removed.items()))
    notes += [f"MuJoCo warned: {clip(text)}" for text in said]
    return MjcfDocument(spec, model, xml, tuple(files), notes)
