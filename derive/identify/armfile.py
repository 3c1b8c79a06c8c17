"""The identified arm file: the original with the identified values, everything else kept.

tomlkit edits the user's file in place (comments, layout, key order and every other
section kept, as derive sweep's worst_<controller>.toml): per joint the motor's
``rotor_inertia`` = Ia / gr^2 and the joint's viscous friction = fv minus the motor's
back-EMF damping gr^2 Kt Kv / Ra (``[[motor]] viscous_friction``, or a planar arm's
``[[link]] viscous_friction``); per body, for URDF and DH arms a ``[[body_override]]``
table (derive.model.override: the ten parameters in the joint's frame), for a planar
arm its ``[[link]]`` fields ``mass``, ``com`` and ``inertia`` (the link alone: its point
masses stay as they are). A relative ``urdf`` path is rewritten relative to the new
file's folder. The text is validated as an arm file before anyone writes it. Coulomb
friction is not part of the controller's model and goes into the report only.
"""
from __future__ import annotations

import os
import tomllib
from pathlib import Path

import numpy as np
import tomlkit

from derive.errors import DataError, DerivationError, SpecError
from derive.identify.run import Identification
from derive.model.spec import arm_from_dict, resolve_arm_path

_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


DIGITS = 12     # significant digits written (the solver's last digits are noise; the LMI margin is 1e-9)


def _number(x: float) -> float:
    """A value as the file holds it: DIGITS significant digits, -0.0 written as 0.0."""
    return float(f"{float(x):.{DIGITS}g}") + 0.0


def _set(table, key: str, value) -> None:
    """table[key] = value, its comment saying it is identified and what the file had."""
    old = table.get(key)
    item = tomlkit.item(value)
    if old is None:
        item.comment("identified")
    else:
        note = old.trivia.comment.lstrip("#").strip() if hasattr(old, "trivia") else ""
        shown = old.unwrap() if hasattr(old, "unwrap") else old
        item.comment(f"identified (was {shown!r}{': ' + note if note else ''})")
    table[key] = item


def _motors(doc, n: int):
    """The [[motor]] array of tables, created (gear ratio 1, torque actuation) when absent."""
    if "motor" not in doc:
        aot = tomlkit.aot()
        for _ in range(n):
            aot.append(tomlkit.table())
        doc.add(tomlkit.nl())
        doc.add("motor", aot)
    return doc["motor"]


def identified_text(idn: Identification, source_text: str, source: Path, out: Path, log_name: str) -> str:
    """The identified arm file's text (module docstring). DerivationError if it does not load."""
    arm, n = idn.arm, idn.arm.n
    doc = tomlkit.parse(source_text)
    phi = idn.cons.phi
    gears = [float(m.gear_ratio) for m in arm.motors]
    motors = _motors(doc, n)
    base = 10 * n
    for j in range(n):
        # the estimate holds Ia >= 0 to its solver's tolerance only (Clarabel gave the Panda's -2e-11 kg m^2)
        _set(motors[j], "rotor_inertia", _number(max(phi[base + j], 0.0) / gears[j] ** 2))
        bv = _number(max(phi[base + n + j] - idn.emf[j], 0.0))
        _set(motors[j] if arm.spatial is not None else doc["link"][j], "viscous_friction", bv)
    if arm.spatial is not None:
        doc.pop("body_override", None)
        aot = tomlkit.aot()
        for i, joint in enumerate(arm.chain.joints):
            b = phi[10 * i: 10 * i + 10]
            t = tomlkit.table()
            t.add("joint", joint.name)
            t.add("mass", _number(b[0]))
            t.add("first_moment", [_number(x) for x in b[1:4]])
            I = np.zeros((3, 3))
            for k, (a, c) in enumerate(_INDEX):
                I[a, c] = I[c, a] = b[4 + k]
            t.add("inertia", [[_number(x) for x in row] for row in I])
            aot.append(t)
        doc.add(tomlkit.nl())
        doc.add(tomlkit.comment(f"identified by derive identify from {log_name}: each body's ten parameters in "
                                "its joint's frame (derive.model.override)"))
        doc.add("body_override", aot)
        relocate_urdf(doc, source, out)
    else:
        z = idn.cons.z
        for i in range(n):
            m, hx, izz = z[3 * i: 3 * i + 3]
            link = doc["link"][i]
            com = hx / m if m > 0 else 0.0
            _set(link, "mass", _number(m))
            _set(link, "com", _number(com))
            _set(link, "inertia", _number(max(izz - m * com * com, 0.0)))
    text = (f"# identified by derive identify from {log_name} (report beside this file); the original: "
            f"{source.name}\n" + tomlkit.dumps(doc))
    data = tomllib.loads(text)
    if arm.spatial is not None and "urdf" in data.get("arm", {}):     # checked before out's folder exists
        data["arm"]["urdf"] = str(urdf_target(source, source_text))
    try:
        arm_from_dict(data, str(out), out.parent)
    except (SpecError, tomllib.TOMLDecodeError) as exc:
        raise DerivationError(f"identify: the identified arm file does not load ({exc})") from None
    return text


def urdf_target(source: Path, source_text: str) -> Path:
    """The absolute path of the original arm file's URDF."""
    path = Path(str(tomllib.loads(source_text)["arm"]["urdf"]))
    return Path(os.path.abspath(path if path.is_absolute() else source.parent / path))


def relocate_urdf(doc, source: Path, out: Path) -> None:
    """A relative ``urdf`` path made relative to the new file's folder."""
    table = doc.get("arm")
    if table is None or "urdf" not in table or os.path.isabs(str(table["urdf"])):
        return
    target = os.path.abspath(source.parent / str(table["urdf"]))
    table["urdf"] = Path(os.path.relpath(target, Path(os.path.abspath(out.parent)))).as_posix()


def outputs(arm_arg, out: Path | None, report: Path | None, arm, suffix: str) -> tuple[Path, Path, Path]:
    """The arm file read (ARM, ``arm_arg``), the one identify writes (``--out``, default ``<arm>_<suffix>.toml``)
    and its report folder (``--report``, default ``<out>_report``); DataError when --out names the arm file."""
    source = resolve_arm_path(arm_arg)
    out = out if out is not None else Path(f"{arm.name}_{suffix}.toml")
    if out.exists() and out.resolve() == source.resolve():
        raise DataError(f"--out {out}: expected a new file, got the arm file itself (it would be replaced)")
    return source, out, report if report is not None else out.with_name(out.stem + "_report")
