"""MJCF arm files: ``mjcf = "robot.xml"`` under ``[arm]`` -> a :class:`Chain`.

::

    [arm]
    mjcf = "panda.xml"             # path relative to the arm file (MuJoCo's XML)
    base_body = "link0"            # the chain runs from this body ...
    tip_body = "hand"              # ... to this one
    locked = { finger_joint1 = 0.0 }   # joints held at a value (rad or m; MuJoCo's qpos)

MuJoCo's own compiler reads the file (derive.model.mjcf_xml: read safely, includes expanded,
geometry that needs files removed, compiled); derive converts the compiled body tree, which
holds every frame, inertia and joint in canonical form, into the chain the URDF reader
(derive.model.urdf) produces. Nothing downstream knows which reader ran.

From the compiled ``MjModel``: ``body_pos``/``body_quat`` (each body's frame in its parent's),
``body_mass``/``body_ipos``/``body_iquat``/``body_inertia`` (mass, centre of mass, principal axes
and moments: MuJoCo's diagonalisation of ``fullinertia``), ``jnt_type``/``jnt_pos``/``jnt_axis``
(joint anchor and axis in its body's frame), ``qpos0`` (a joint's ``ref``), ``jnt_range`` and
``jnt_limited`` (limits; radians whatever the compiler's ``angle``), ``dof_armature`` (the
reflected rotor inertia: the default of ``motor.rotor_inertia``, with gear ratio 1),
``dof_damping`` (viscous friction: the default of ``motor.viscous_friction``),
``dof_frictionloss`` (dry friction: the default of ``simulation.coulomb_friction``), and the
actuators on a chain joint: effort limit = gear x ``forcerange`` when force-limited, else
gear x gain x ``ctrlrange`` for a plain motor (force = gain ctrl), the joint's
``actuatorfrcrange`` bounding both (an asymmetric range gives its smaller side).

Joints: a hinge is a revolute joint (continuous when it has no range), a slide a prismatic
one; a ball or free joint on the chain, or a body with two moving joints on it, is refused.
Chain joint i's frame F_i is its body's frame moved to the joint's anchor; q_i is MuJoCo's qpos
(the origin turned by -ref, so that q = ref is the model pose). Bodies below a chain joint
without a joint, or whose joints are held (off the chain: at ``locked``'s value, else 0; a ball
or free joint at the model pose), are merged into the body of the chain joint above them, as
the URDF reader merges fixed links. Bodies above the base body or beside the chain do not move
and are left out. Equality constraints, tendons, springs, contacts and MuJoCo's gravity
compensation are not part of derive's chain (noted, or warned when on the chain).

Numbers are exact: a compiled double is the Rational of its shortest decimal
(derive.model.rigid.rational: the file's own text when MuJoCo kept it); a body's inertia about
its centre of mass is MuJoCo's principal moments turned back by its principal axes (exact), each
entry then rounded to its nearest double (that is the file's ``fullinertia`` entry again, to the
last bit of MuJoCo's diagonalisation; kept exact when rounding would make it non-physical); a rotation within
1e-8 rad of a quarter-turn rotation is that rotation exactly, any other is the exact
rotation of the compiled quaternion (R(q) / |q|^2 of its decimals: exactly orthogonal); an
axis within 1e-12 of a coordinate axis is that axis, any other the nearest rational unit vector.
"""
from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp

from derive.errors import Problem
from derive.model.chain import Body, Chain, Joint, JointType, Limits, Parameter, Transform
from derive.model.fields import Reader, show
from derive.model.mjcf_xml import read_mjcf
from derive.model.rigid import (NEAR_MISS, SNAP_TOLERANCE, axis_angle, body_from_com, empty_body,
                                inertia_problem, merge, move, quaternion_rotation, rational, tidy, unit_axis)
from derive.model.urdf import UrdfChain, body_parameters, locked_table, name_choice

FIELD = "arm.mjcf"
HINGE, SLIDE, BALL, FREE = 3, 2, 1, 0     # mjtJoint


def _field(kind: str, name: str, what: str = "") -> str:
    return f"mjcf {kind} {name!r}" + (f" {what}" if what else "")


class _Tree:
    """The compiled model's body tree, read once: names, parents, children, joints per body."""

    def __init__(self, model: Any):
        self.m = model
        self.names = [model.body(b).name or f"(body {b})" for b in range(model.nbody)]
        self.parent = [int(x) for x in model.body_parentid]
        self.children: dict[int, list[int]] = {}
        for b in range(1, model.nbody):
            self.children.setdefault(self.parent[b], []).append(b)
        self.joints = {b: list(range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b])))
                       for b in range(model.nbody)}
        self.joint_names = [model.joint(j).name for j in range(model.njnt)]

    def pose(self, b: int, log: list) -> Transform:
        R, off = quaternion_rotation(self.m.body_quat[b])
        if off is not None and off > 1e-12:
            log.append((off, f"body {self.names[b]!r}"))
        return Transform(R, sp.ImmutableMatrix([rational(float(x)) for x in self.m.body_pos[b]]))

    def body(self, b: int, log: list) -> Body:
        """Body b's inertial in its own frame (MuJoCo's principal axes turned back)."""
        m = self.m
        R, off = quaternion_rotation(m.body_iquat[b])
        if off is not None and off > 1e-12:
            log.append((off, f"body {self.names[b]!r} <inertial>"))
        mass = rational(float(m.body_mass[b]))
        if mass == 0:
            return empty_body()
        exact = (R * sp.diag(*[rational(float(x)) for x in m.body_inertia[b]]) * R.T).applyfunc(sp.expand)
        rounded = exact.applyfunc(lambda e: rational(float(e)))   # the file's fullinertia, to the last bit
        inertia = rounded if rounded == rounded.T and inertia_problem(rounded) is None else exact
        return body_from_com(mass, sp.Matrix([rational(float(x)) for x in m.body_ipos[b]]), inertia)


def _choice(r: Reader, d: dict, key: str, tree: _Tree) -> int | None:
    """The body id ``d[key]`` names, or None after a problem (derive.model.urdf.name_choice)."""
    name = name_choice(r, d, key, tree.names[1:], "body of the MJCF")
    return None if name is None else tree.names.index(name, 1)


def _locked(r: Reader, value: Any, tree: _Tree) -> dict[str, sp.Expr]:
    kinds = {n: {HINGE: "hinge", SLIDE: "slide", BALL: "ball", FREE: "free"}[int(tree.m.jnt_type[j])]
             for j, n in enumerate(tree.joint_names) if n}
    return locked_table(r, value, kinds, {"hinge": True, "slide": False}, "MJCF")


def _motion(tree: _Tree, j: int, value: sp.Expr) -> Transform:
    """Joint j moved from the model pose to qpos = ``value`` (ball and free: the model pose),
    about or along its anchor and axis in its body's frame: x_before = T x_after."""
    m, kind = tree.m, int(tree.m.jnt_type[j])
    if kind not in (HINGE, SLIDE):
        return Transform.identity()
    axis, _ = unit_axis(m.jnt_axis[j])
    turn = sp.expand(value - rational(float(m.qpos0[m.jnt_qposadr[j]])))
    if turn == 0:
        return Transform.identity()
    if kind == SLIDE:
        return Transform(sp.ImmutableMatrix.eye(3), sp.ImmutableMatrix(sp.Matrix(axis) * turn))
    a = sp.Matrix([rational(float(x)) for x in m.jnt_pos[j]])
    R = axis_angle(axis, turn)
    return tidy(Transform(R, sp.ImmutableMatrix(a - R * a)))


def _effort(tree: _Tree, j: int) -> tuple[Fraction | None, str]:
    """Joint j's effort limit from the actuators on it and its actuatorfrcrange (module docstring)."""
    m = tree.m
    limits, said = [], []
    for a in range(m.nu):
        if int(m.actuator_trntype[a]) != 0 or int(m.actuator_trnid[a][0]) != j:   # mjTRN_JOINT
            continue
        gear = abs(float(m.actuator_gear[a][0]))
        if m.actuator_forcelimited[a]:
            lo, hi = (float(x) for x in m.actuator_forcerange[a])
            limits.append(gear * min(abs(lo), abs(hi)))
            said.append(f"forcerange x gear of actuator {m.actuator(a).name or a!r}")
        elif (m.actuator_ctrllimited[a] and int(m.actuator_gaintype[a]) == 0 and int(m.actuator_biastype[a]) == 0
              and int(m.actuator_dyntype[a]) == 0):
            lo, hi = (float(x) for x in m.actuator_ctrlrange[a])
            limits.append(gear * abs(float(m.actuator_gainprm[a][0])) * min(abs(lo), abs(hi)))
            said.append(f"ctrlrange x gain x gear of motor {m.actuator(a).name or a!r}")
        else:
            return None, ""   # an actuator without a torque bound: the joint has none
    if m.jnt_actfrclimited[j]:
        lo, hi = (float(x) for x in m.jnt_actfrcrange[j])
        bound = min(abs(lo), abs(hi))
        if not limits or sum(limits) > bound:
            return Fraction(repr(bound)), "the joint's actuatorfrcrange"
    if not limits:
        return None, ""
    return Fraction(repr(sum(limits))), " + ".join(said)


def _limits(tree: _Tree, j: int) -> tuple[Limits, str]:
    m = tree.m
    effort, source = _effort(tree, j)
    if not m.jnt_limited[j]:
        return Limits(effort=effort), source
    lo, hi = (Fraction(repr(float(x))) for x in m.jnt_range[j])
    return Limits(lo, hi, None, effort), source


def mjcf_chain(r: Reader, d: dict, base_dir: Path, gravity: Parameter, direction: sp.Matrix) -> UrdfChain | None:
    """The chain of the MJCF named by the ``[arm]`` table ``d`` (module docstring), or None after
    adding its problems (each naming the body, joint or arm-file field) to ``r``."""
    doc = read_mjcf(r, FIELD, d.get("mjcf"), base_dir)
    if doc is None:
        return None
    tree = _Tree(doc.model)
    base, tip = _choice(r, d, "base_body", tree), _choice(r, d, "tip_body", tree)
    locked = _locked(r, d.get("locked"), tree)
    if d.get("repair_inertia"):
        r.add("arm.repair_inertia", "false or absent for an MJCF (MuJoCo's compiler refuses a non-physical inertia "
              "before derive reads it: correct the file's <inertial>)", show(d.get("repair_inertia")))
    if base is None or tip is None or r.problems:
        return None
    if base == tip:
        r.add("arm.tip_body", f"a body below the base body {tree.names[base]!r}", f"{tree.names[tip]!r}: base and "
              "tip are the same body")
        return None
    path, b = [], tip
    while b != base:
        if b == 0:
            r.add("arm.tip_body", f"a body below base_body {tree.names[base]!r} (the chain runs from base to tip)",
                  f"{tree.names[tip]!r}, whose chain to the world body does not pass {tree.names[base]!r}")
            return None
        path.append(b)
        b = tree.parent[b]
    path.reverse()
    moving = _chain_joints(r, tree, path, locked)
    if moving is None:
        return None
    return _build(r, tree, base, set(path), moving, locked, doc.notes, gravity, direction, tip)


def _chain_joints(r: Reader, tree: _Tree, path: list[int], locked: dict) -> dict[int, int] | None:
    """body -> its chain joint, for the bodies of the path; problems for ball/free joints, two
    moving joints on a body, a held joint after the moving one, an unnamed chain joint."""
    out = {}
    for b in path:
        joints = tree.joints[b]
        free = [j for j in joints if tree.joint_names[j] not in locked]
        odd = [j for j in free if int(tree.m.jnt_type[j]) not in (HINGE, SLIDE)]
        for j in odd:
            kind = "ball" if int(tree.m.jnt_type[j]) == BALL else "free"
            r.add(_field("body", tree.names[b], f"<joint {tree.joint_names[j] or '(unnamed)'!r}>"),
                  "hinge or slide joints on the chain from base to tip (choose a base body below it or a tip body "
                  "above it)", f"a {kind} joint")
        if odd:
            continue
        if len(free) > 1:
            r.add(_field("body", tree.names[b]), "at most one moving joint per body on the chain (derive's chain "
                  "has one joint per body; lock the others with locked = { name = 0.0 } under [arm])",
                  f"{len(free)} joints: {', '.join(repr(tree.joint_names[j] or '(unnamed)') for j in free)}")
            continue
        if free:
            j = free[0]
            if not tree.joint_names[j]:
                r.add(_field("body", tree.names[b], "<joint>"), "a named joint on the chain (derive names its "
                      "joints after the file's)", "a joint without a name")
            if any(k > j for k in joints):
                r.add(_field("joint", tree.joint_names[j]), "the held joints of its body before it", "a locked "
                      "joint after it in the same body")
            out[b] = j
    if not out and not r.problems:
        r.add("arm.tip_body", "a tip body with at least one hinge or slide joint between it and base_body",
              "a chain without moving joints")
    return None if r.problems else out


def _build(r: Reader, tree: _Tree, base: int, on_path: set[int], moving: dict[int, int], locked: dict,
           notes: list[str], gravity: Parameter, direction: sp.Matrix, tip: int = -1) -> UrdfChain | None:
    m = tree.m
    joints: list[Joint] = []
    bodies: list[Body] = []
    members: list[list[str]] = []
    damping, friction, armature = [], [], []
    merged, held_text, held, efforts, log = [], [], {}, [], []
    stack = [(base, -1, Transform.identity())]    # (body, owning chain joint or -1, F_owner <- body frame)
    tip_frame = None   # the tip body's frame in F_n (Chain.tip: where a payload's centre of mass is given)
    while stack:
        b, owner, T = stack.pop()
        if b == tip:
            tip_frame = T
        if owner >= 0:
            bodies[owner] = merge(bodies[owner], move(tree.body(b, log), T))
            members[owner].append(tree.names[b])
        for c in reversed(tree.children.get(b, [])):
            if owner < 0 and c not in on_path:
                continue    # beside the chain, above its first joint: does not move
            Tc = T.compose(tree.pose(c, log))
            chain_joint = moving.get(c)
            for j in tree.joints[c]:
                if j == chain_joint:
                    break
                name = tree.joint_names[j]
                value = locked.get(name, sp.Integer(0))
                Tc = Tc.compose(_motion(tree, j, value))
                if int(m.jnt_type[j]) in (HINGE, SLIDE):
                    held[name or f"(joint {j})"] = value
                held_text.append(f"{name or '(unnamed)'!r} at {value}" if int(m.jnt_type[j]) in (HINGE, SLIDE)
                                 else f"{name or '(unnamed)'!r} ({'ball' if int(m.jnt_type[j]) == BALL else 'free'}) "
                                 "at the model pose")
            if chain_joint is None:
                if owner >= 0 and not tree.joints[c]:
                    merged.append(repr(tree.names[c]))
                stack.append((c, owner, tidy(Tc)))
                continue
            j = chain_joint
            axis, exact = unit_axis(m.jnt_axis[j])
            if not exact:
                notes.append(f"joint {tree.joint_names[j]!r}: axis ({', '.join(f'{float(x):.17g}' for x in m.jnt_axis[j])}) "
                             "made the nearest rational unit vector (within 4e-18)")
            ref = rational(float(m.qpos0[m.jnt_qposadr[j]]))
            hinge = int(m.jnt_type[j]) == HINGE
            anchor = sp.Matrix([rational(float(x)) for x in m.jnt_pos[j]]) if hinge else sp.zeros(3, 1)
            undo = axis_angle(axis, -ref) if hinge else sp.eye(3)
            shift = sp.zeros(3, 1) if hinge else -sp.Matrix(axis) * ref
            origin = tidy(Tc.compose(Transform(sp.ImmutableMatrix(undo), sp.ImmutableMatrix(anchor + shift))))
            limits, source = _limits(tree, j)
            kind = (JointType.REVOLUTE if m.jnt_limited[j] else JointType.CONTINUOUS) if hinge else JointType.PRISMATIC
            joints.append(Joint(tree.joint_names[j], kind, origin, axis, limits, _field("joint", tree.joint_names[j])))
            if source:
                efforts.append(f"{tree.joint_names[j]!r} {float(limits.effort):g} ({source})")
            dof = int(m.jnt_dofadr[j])
            damping.append(Fraction(repr(float(m.dof_damping[dof]))))
            armature.append(Fraction(repr(float(m.dof_armature[dof]))))
            loss = float(m.dof_frictionloss[dof])
            friction.append(Fraction(repr(loss)) if loss else None)
            bodies.append(empty_body())
            members.append([])
            stack.append((c, len(joints) - 1, Transform(sp.ImmutableMatrix.eye(3), sp.ImmutableMatrix(-anchor))))
    _notes(tree, joints, damping, armature, friction, merged, held_text, efforts, log, notes)
    params, symbolic = body_parameters(bodies, members, joints, "mjcf body")
    vector = sp.ImmutableMatrix((gravity.symbol * sp.Matrix(direction)).applyfunc(sp.expand))
    chain = Chain(tuple(joints), tuple(symbolic), vector, tuple(params) + (gravity,), tuple(notes),
                  held=tuple((name, float(v)) for name, v in sorted(held.items())),
                  tip=None if tip_frame is None or tip_frame == Transform.identity() else tip_frame)
    return UrdfChain(chain, tuple(damping), tuple(_field("joint", j.name, "damping") for j in joints),
                     tuple(friction), tuple(_warnings(tree, moving)), armature=tuple(armature))


def _notes(tree: _Tree, joints, damping, armature, friction, merged, held_text, efforts, log, notes) -> None:
    m = tree.m
    for what, values, use in (("damping", damping, "the viscous friction bv (the default of motor.viscous_friction)"),
                              ("armature", armature, "the rotor inertia reflected to the joint (the default of "
                               "motor.rotor_inertia, gear_ratio 1)"),
                              ("frictionloss", friction, "the Coulomb friction in the simulation and the plant FMU "
                               "(the default of simulation.coulomb_friction)")):
        given = [f"{j.name!r} {float(x):g}" for j, x in zip(joints, values) if x]
        if given:
            notes.append(f"{what} of joint{'s' if len(given) > 1 else ''} {', '.join(given)}: {use}")
    if efforts:
        notes.append("effort limits from the MJCF's actuators: " + ", ".join(efforts))
    if merged:
        notes.append(f"bodies without a joint merged into the body of the moving joint above them: {', '.join(merged)}")
    if held_text:
        notes.append(f"joints held (locked) and their bodies merged: {', '.join(held_text)}")
    for j in joints:
        if j.type is JointType.CONTINUOUS:
            notes.append(f"joint {j.name!r} is a hinge without a range: continuous (one angle)")
    snapped = [f"{where} ({off:.2g} rad off)" for off, where in log if off <= SNAP_TOLERANCE]
    kept = [f"{where} ({off:.2g} rad from it)" for off, where in log if SNAP_TOLERANCE < off <= NEAR_MISS]
    if snapped:
        notes.append(f"rotations within {SNAP_TOLERANCE:g} rad of a quarter-turn rotation snapped to it: "
                     + ", ".join(snapped[:4]) + (f" and {len(snapped) - 4} more" if len(snapped) > 4 else ""))
    if kept:
        notes.append(f"rotations near a quarter-turn rotation but more than {SNAP_TOLERANCE:g} rad from it, kept "
                     "as compiled: " + ", ".join(kept[:4]) + (f" and {len(kept) - 4} more" if len(kept) > 4 else ""))
    counts = [f"{k} {what}" for what, k in (("equality constraints", m.neq), ("tendons", m.ntendon),
                                            ("actuators (read for effort limits only)", m.nu),
                                            ("sensors", m.nsensor)) if k]
    if counts:
        notes.append("not part of derive's chain: " + ", ".join(counts))


def _warnings(tree: _Tree, moving: dict[int, int]) -> list[Problem]:
    """What MuJoCo would do on the chain that derive's chain does not model: springs, gravity
    compensation (printed by every command)."""
    m, out = tree.m, []
    for b, j in moving.items():
        name = tree.joint_names[j]
        if np.any(np.asarray(m.jnt_stiffness[j]) != 0):
            out.append(Problem(_field("joint", name, "stiffness"), "no joint spring (derive's chain has none; not "
                               "read)", f"{float(np.ravel(m.jnt_stiffness[j])[0]):g}"))
    grav = [tree.names[b] for b in range(1, m.nbody) if float(m.body_gravcomp[b]) != 0]
    if grav:
        out.append(Problem("mjcf bodies " + ", ".join(map(repr, grav[:4])) + (" ..." if len(grav) > 4 else "")
                           + " gravcomp", "no gravity compensation (derive's gravity acts on every body; not read)",
                           "gravcomp set"))
    return out


def gravity_in_base(model: Any, base: str) -> tuple[float, tuple[float, float, float]]:
    """MuJoCo's gravity (``<option gravity>``, world frame) as a magnitude [m/s^2] and a unit
    direction in the base body's frame at the model pose ((0, 0, -1) when there is no gravity)."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    g = np.array(model.opt.gravity, dtype=float)
    size = float(np.linalg.norm(g))
    if size == 0.0:
        return 0.0, (0.0, 0.0, -1.0)
    R = data.xmat[model.body(base).id].reshape(3, 3)
    v = R.T @ g / size
    v = [0.0 if abs(x) <= 1e-12 else (round(x) if abs(abs(x) - 1) <= 1e-12 else float(x)) for x in v]
    return size, tuple(float(x) for x in v)
