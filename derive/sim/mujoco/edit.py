"""Edits of a MuJoCo model spec for derive's plant (derive.sim.mujoco.model, steps 1, 3, 4):
the geometry that needs files removed, the file's own actuators and constraints removed, the
joints derive does not move held where it holds them, each body's owning joint."""
from __future__ import annotations

import math

import numpy as np

from derive.errors import DeriveError


def fail(src, what: str) -> DeriveError:
    """One error naming the model file and the arm-file field that names it."""
    return DeriveError(f"{src.field} {src.shown!r}: {what}")


def strip_geometry(mj, src, spec) -> dict[str, int]:
    """Remove mesh, height-field and SDF geoms and every asset that needs a file (meshes, height
    fields, textures, materials, skins), so MuJoCo reads no file but the model's; a body whose
    inertia MuJoCo would compute from such a geom is an error (give it an <inertial>)
    (derive.model.mjcf_xml.strip_file_geometry)."""
    from derive.model.mjcf_xml import strip_file_geometry

    removed, inferred = strip_file_geometry(mj, spec)
    if inferred:
        body, kind, geom = inferred[0]
        raise fail(src, f"expected body {body!r} to give its mass and inertia (an <inertial>), got them computed "
                        f"from its {kind} geom {geom!r}, whose file derive does not read")
    return removed


def fix_unmoved(mj, spec, base: str | None, chain: set[str], held: dict[str, float]) -> list[str]:
    """Remove, before MuJoCo first compiles the file, every joint derive never moves whose removal
    leaves its body where derive has it: the joints outside the subtree below the ``base`` body (of the
    base itself, above or beside the chain: a mobile base, a free joint) and the joints not in ``chain`` held at their
    model value (``held``'s value, default 0, equal to the joint's ``ref``). Return what was held, as
    'name at value'."""
    fixed = []
    for sj in list(spec.joints):
        if sj.name in chain:
            continue
        inside = base is None    # the base a strict ancestor of the joint's body: the joint is below the base
        body = sj.parent.parent if sj.parent is not None and sj.parent.name != "world" else None
        while body is not None and not inside:
            inside = body.name == base
            body = body.parent if body.name != "world" else None
        moving = sj.type in (mj.mjtJoint.mjJNT_HINGE, mj.mjtJoint.mjJNT_SLIDE)
        if inside and moving and held.get(sj.name, 0.0) != float(sj.ref):
            continue   # held elsewhere than the model pose: hold() moves its body after the compile
        if inside and not moving:
            continue   # a ball or free joint below the base: hold() fixes it and says so
        fixed.append(f"{sj.name or '(unnamed)'} at " + (f"{held.get(sj.name, 0.0):g}" if inside else
                                                         "the model pose (above or beside the chain's base)"))
        spec.delete(sj)
    return fixed


def strip_file_elements(spec) -> dict[str, int]:
    """Remove the file's constraints, tendons, actuators, sensors and keyframes (module
    docstring, step 3); count them."""
    removed = {}
    for kind in ("equalities", "tendons", "actuators", "sensors", "keys"):
        items = list(getattr(spec, kind))
        for item in items:
            spec.delete(item)
        if items:
            removed[kind] = len(items)
    return removed


def _quat_mul(a, b) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _rotation(q) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def hold(mj, src, spec, ref, keep: set[int], locked: dict[str, float]) -> list[str]:
    """Remove every joint not in ``keep`` (reference ids), fixing its body where it is held;
    return what was held, as 'name at value'."""
    held = []
    by_body: dict[int, list[int]] = {}
    for j in range(ref.njnt):
        by_body.setdefault(int(ref.jnt_bodyid[j]), []).append(j)
    for body, joints in by_body.items():
        pos, quat = ref.body_pos[body].copy(), ref.body_quat[body].copy()
        moved = False
        for k, j in enumerate(joints):
            if j in keep:
                if any(other not in keep for other in joints[k + 1:]):
                    raise fail(src, f"expected the held joints of body {ref.body(body).name!r} before its moving "
                                     f"ones, got {ref.joint(joints[-1]).name!r} after {ref.joint(j).name!r}")
                continue
            name, kind = ref.joint(j).name, mj.mjtJoint(ref.jnt_type[j])
            value = locked.get(name, 0.0)
            if kind in (mj.mjtJoint.mjJNT_HINGE, mj.mjtJoint.mjJNT_SLIDE) and value != 0.0:
                axis, anchor = ref.jnt_axis[j], ref.jnt_pos[j]
                R = _rotation(quat)
                if kind == mj.mjtJoint.mjJNT_SLIDE:
                    pos = pos + R @ (axis * value)
                else:
                    angle = value - float(ref.qpos0[ref.jnt_qposadr[j]])
                    turn = np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])
                    pos = pos + R @ (anchor - _rotation(turn) @ anchor)
                    quat = _quat_mul(quat, turn)
                moved = True
            elif value != 0.0:
                raise fail(src, f"expected a hinge or slide joint for arm.locked.{name} = {value:g}, got a "
                                 f"{str(kind).split('_')[-1].lower()} joint (it is held at the model pose)")
            held.append(f"{name} at {value:g}")
            spec.delete(spec.joint(name) if name else _joint_by_id(spec, j))
        if moved:
            sb = _body_by_id(spec, body)
            sb.pos, sb.quat = pos, quat / np.linalg.norm(quat)
            sb.alt.type = mj.mjtOrientation.mjORIENTATION_QUAT
    return held


def _joint_by_id(spec, j):
    return next(x for x in spec.joints if x.id == j)


def _body_by_id(spec, b):
    return next(x for x in spec.bodies if x.id == b)


def owners(ref, joint_bodies: list[int]) -> list[int]:
    """Per reference body, the index of the mapped joint that moves it (-1: the base side)."""
    index = {b: i for i, b in enumerate(joint_bodies)}
    owner = [-1] * ref.nbody
    for b in range(1, ref.nbody):
        up = b
        while up != 0 and up not in index:
            up = int(ref.body_parentid[up])
        owner[b] = index.get(up, -1)
    return owner
