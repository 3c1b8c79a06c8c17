"""The MuJoCo model of one run: the user's file (:mod:`.source`) with derive's joints
mapped, the rest held, derive's drives and the ``[simulation]`` mismatch; MuJoCo's own
model-compilation API (``MjSpec``) does every edit.

Steps:

1. MuJoCo parses the file; its mesh, height-field and SDF geoms and the assets that need
   files go (derive.sim.mujoco.edit.strip_geometry: no file is read); MuJoCo compiles it as
   written (the reference: every frame, axis and inertia resolved by MuJoCo, static bodies
   kept apart).
2. **Mapping**: derive's chain joint i is MuJoCo's joint of the same name, a hinge for a
   revolute or continuous joint, a slide for a prismatic one; the joints must follow each
   other down one branch of the body tree. One DeriveError names the first that does not.
3. **Held joints**: every other joint is removed and its body fixed where derive holds it
   (the arm file's ``locked`` value, a URDF mimic's rule, default 0: the body's frame is moved
   by that joint motion); free and ball joints are fixed at the model pose. The joints above the
   chain's base (a mobile base's virtual joints, a free joint) and those held at the model pose
   are removed before MuJoCo first compiles the file, so a massless virtual link that derive
   never moves does not stop MuJoCo's compiler. Equality constraints,
   tendons, actuators, sensors and keyframes of the file are removed (derive's chain has
   none; they are counted in the description).
4. **Bodies**: each body's inertial is set to what step 1 resolved (so geometry no
   longer matters), then the mismatch: ``link_mass_scale[i]`` multiplies the mass and
   inertia of what derive's plant scales (the body joint i moves for a planar arm, whose
   welded bodies are point masses; every body joint i carries for a URDF or DH arm), and
   ``payload_scale`` the bodies welded below the last joint when derive's arm has point
   masses on its last link (planar arms; a URDF arm has none, in either plant); ``payload_mass``
   a body welded to the tip body (:mod:`.payload`).
5. **Joints**: derive's drive as a MuJoCo ``general`` actuator on each joint, input
   ctrl = u + d: voltage, gain Kt/R, bias -Kt Kv/R times the motor speed, gear gr (tau =
   gr Kt (u - gr Kv theta')/R, eq. 11-12: MuJoCo's actuator velocity is gr theta'; its own
   ``dcmotor`` assumes Kt = Kv and is not used); torque, gain 1, gear gr. Rotor inertia gr^2 Jm is ``armature``. Damping,
   friction loss and limits: ``friction="file"`` keeps the file's (URDF ``<dynamics
   damping friction>``), ``"off"`` sets derive's (damping bv, no friction loss, no limits,
   no springs: both plants then have the same parameters); ``[simulation]
   viscous_friction`` is added to the damping either way. The arm's own MJCF
   (``[arm] mjcf``): its ``armature`` is derive's rotor inertia (gr^2 Jm, whose default it
   is), not added to it, and its gravity compensation is off (derive's chain has none). The smooth Coulomb friction of
   ``[simulation] coulomb_friction`` (its widths ``coulomb_smoothing``) is applied by the loop (:mod:`.loop`) on
   every joint whose file gives no friction loss: where it does (``"file"``), MuJoCo's own dry friction
   is that joint's Coulomb friction, not both.
6. **Options**: RK4 at h = sample_time / substeps (the derived plant's step), gravity
   g * gravity_direction of the arm file turned from derive's base frame into MuJoCo's
   world, contacts off unless ``[simulation] mujoco_contacts = true`` asks for them (then
   between an MJCF's primitive geoms, with ``friction="file"``; a URDF has no geometry left),
   the constraint solver off when nothing needs it,
   no automatic reset (a diverging run reports non-finite values like derive's plant).
   Static bodies are fused when MuJoCo can (fewer bodies, same inertia); without contacts
   the geoms and lights are left out of the run's model (they exert nothing and every
   inertia is explicit; MuJoCo would still place them at each RK4 stage: 10 % of the
   Menagerie Panda's step).
7. The model MuJoCo integrates is written back as MJCF (:attr:`Compiled.xml`, MjSpec.to_xml):
   ``derive simulate --plant mujoco`` saves it beside its outputs, for MuJoCo's viewer.

A body that a kept joint moves with no mass or inertia (a massless link between two joints:
derive's plant runs it, as its bodies below give the joint inertia) is refused by MuJoCo's
compiler; derive says which link and how to fix the file, instead of MuJoCo's message.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from difflib import get_close_matches

import numpy as np
import sympy as sp

from derive.errors import DeriveError
from derive.model.actuators import terms
from derive.model.chain import Actuation, JointType
from derive.model.mjcf_xml import MINVAL, collected_warnings, compile_error
from derive.model.simspec import coulomb_widths
from derive.sim.mujoco import require
from derive.sim.mujoco.edit import fail, fix_unmoved, hold, owners, strip_file_elements, strip_geometry
from derive.sim.mujoco.payload import weld_payload

FRICTION = ("file", "off")


@dataclass(frozen=True)
class Drive:
    """Joint i's drive in MuJoCo's terms, from the true plant's values: actuator gain and
    motor-speed bias per unit of ctrl (before the gear), gear, derive's joint damping bv,
    armature gr^2 Jm."""

    gain: float
    bias: float
    gear: float
    damping: float
    armature: float


@dataclass
class Compiled:
    """A compiled model: ``model`` (mujoco.MjModel), the position and velocity addresses of
    derive's joints, the smooth Coulomb friction tau_c per joint the loop adds [N m], and the
    plant's description (what the metrics file states)."""

    model: object
    qadr: np.ndarray
    dadr: np.ndarray
    coulomb: np.ndarray
    description: dict
    xml: str = ""


def drives(d, values: tuple[float, ...]) -> list[Drive]:
    """The drives of derivation ``d`` at the plant's parameter values (``d.values`` order)."""
    rep = {sym: v for (sym, _), v in zip(d.values, values)}
    out = []
    for act in d.dynamics.chain.actuators:
        b, damping, armature = (float(sp.sympify(x).xreplace(rep)) for x in terms(act))
        gr, bv = float(act.gear_ratio.xreplace(rep)), float(act.viscous_friction.xreplace(rep))
        if act.actuation is Actuation.VOLTAGE:
            kt, kv, ra = (float(x.xreplace(rep)) for x in (act.torque_constant, act.voltage_constant, act.resistance))
            out.append(Drive(kt / ra, -kt * kv / ra, gr, bv, armature))
        else:
            out.append(Drive(b / gr, 0.0, gr, bv, armature))
    return out




def _compile(mj, src, spec, what: str):
    try:
        return spec.compile()
    except Exception as exc:  # noqa: BLE001 - MuJoCo raises ValueError with its own message
        element, said = compile_error(str(exc))
        if MINVAL in said and element.count("'") >= 2:
            raise fail(src, _massless(spec, element.split("'")[1])) from None
        text = " ".join(str(exc).split())
        raise fail(src, f"MuJoCo could not compile the {what}: {text}") from None


def _massless(spec, name: str) -> str:
    """derive's message for a moving body MuJoCo finds massless (module docstring)."""
    body = spec.body(name)
    joints = [j.name for j in body.joints] if body is not None else []
    moved = f"moved by joint {joints[0]!r}; " if joints else ""
    return (f"expected mass and inertia on body {name!r} ({moved}MuJoCo refuses a moving body whose own mass and "
            "inertia, with those welded to it, are below mjMINVAL = 1e-15; derive's plant runs it, as the bodies "
            f"below give the joint its inertia), got none: give {name!r} an <inertial> in the file with the mass "
            "and inertia of what it stands for (a motor, a housing; even 0.01 kg and 1e-6 kg m^2 is closer to the "
            "real arm than none), or hold the joint"
            + (f" (locked = {{ {joints[0]} = 0.0 }} under [arm])" if joints else "") + " if it does not move")


def _names(ref, kinds) -> list[str]:
    mj = require()
    return [ref.joint(j).name for j in range(ref.njnt) if mj.mjtJoint(ref.jnt_type[j]) in kinds]


def _map_joints(mj, src, spec, ref, chain) -> list:
    """derive's joints -> MuJoCo's (module docstring, step 2); the spec joints in chain order."""
    hinge, slide = mj.mjtJoint.mjJNT_HINGE, mj.mjtJoint.mjJNT_SLIDE
    movable = _names(ref, (hinge, slide))
    out = []
    for i, joint in enumerate(chain.joints, 1):
        want = slide if joint.type is JointType.PRISMATIC else hinge
        sj = spec.joint(joint.name)
        if sj is None:
            close = get_close_matches(joint.name, movable, n=3)
            hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
            listed = ", ".join(map(repr, movable[:12])) + (", ..." if len(movable) > 12 else "")
            raise fail(src, f"expected a MuJoCo joint named {joint.name!r} (derive's joint {i}, {joint.field}), "
                             f"got none of that name (MuJoCo's hinge and slide joints: {listed or 'none'}){hint}")
        if sj.type != want:
            raise fail(src, f"expected joint {joint.name!r} (derive's joint {i}) to be a MuJoCo "
                             f"{'slide' if want == slide else 'hinge'} joint ({joint.type.value} in derive), got a "
                             f"{str(sj.type).split('_')[-1].lower()} joint")
        if out:
            body, above = ref.jnt_bodyid[sj.id], ref.jnt_bodyid[out[-1].id]
            while body not in (above, 0):
                body = ref.body_parentid[body]
            if body != above:
                raise fail(src, f"expected joint {joint.name!r} (derive's joint {i}) below joint "
                                 f"{out[-1].name!r} (joint {i - 1}) in MuJoCo's body tree, as derive's chain has it, "
                                 "got it on another branch")
        out.append(sj)
    return out


def _reference(mj, src, chain):
    """The file parsed (an MjSpec) without the geometry it needs files for, compiled as written
    (the reference model) once the joints derive never moves are fixed (module docstring, step 3),
    derive's joints mapped onto it (steps 1-2), and what was removed."""
    with collected_warnings(mj) as said:
        try:
            spec = mj.MjSpec.from_string(src.xml)
        except Exception as exc:  # noqa: BLE001 - MuJoCo's parser raises ValueError with its own message
            raise fail(src, f"MuJoCo could not read it: {' '.join(str(exc).split())}") from None
        if src.kind == "mjcf":
            spec.modelfiledir = src.folder
            spec.compiler.fusestatic = False
        removed = {**strip_geometry(mj, src, spec), **strip_file_elements(spec)}   # nothing names a fixed joint
        names = {j.name for j in chain.joints}
        fixed = fix_unmoved(mj, spec, src.base, names, dict(src.locked)) \
            if all(spec.joint(name) is not None for name in names) else []   # else: _map_joints says which
        ref = _compile(mj, src, spec, "file as written")
    removed.update({f"MuJoCo warned: {text}": 0 for text in said})
    return spec, ref, _map_joints(mj, src, spec, ref, chain), removed, fixed


def check(src, chain) -> None:
    """Raise the DeriveError :func:`build` would raise for a file that does not fit ``chain``
    (derive.model.chain.Chain: the arm's, before any derivation), so a command fails first."""
    _reference(require(), src, chain)


def build(src, d, values: tuple[float, ...], s, friction: str = "file") -> Compiled:
    """The MuJoCo model of one run of derivation ``d`` (module docstring): ``values`` the true
    plant's parameters (derive.sim.plant.TruePlant.values), ``s`` the run's settings,
    ``friction`` "file" or "off". DeriveError naming the file and the joint or body when the
    file does not fit derive's arm."""
    mj = require()
    if friction not in FRICTION:
        raise DeriveError(f"--mujoco-friction: expected one of {', '.join(FRICTION)}, got {friction!r}")
    chain = d.dynamics.chain
    spec, ref, mapped, stripped, fixed = _reference(mj, src, chain)
    ids = [j.id for j in mapped]
    joint_bodies = [int(ref.jnt_bodyid[j]) for j in ids]
    base = ref.body(src.base).id if src.base and src.base in [ref.body(b).name for b in range(ref.nbody)] \
        else int(ref.body_parentid[joint_bodies[0]])
    data = mj.MjData(ref)
    for j in range(ref.njnt):
        if j not in ids and src.locked and ref.joint(j).name in dict(src.locked):
            data.qpos[ref.jnt_qposadr[j]] = dict(src.locked)[ref.joint(j).name]
    mj.mj_kinematics(ref, data)
    to_world = data.xmat[base].reshape(3, 3).copy()
    file_joint = {name: (float(ref.dof_damping[ref.jnt_dofadr[j]]), float(ref.dof_frictionloss[ref.jnt_dofadr[j]]),
                         float(ref.dof_armature[ref.jnt_dofadr[j]]), bool(ref.jnt_limited[j]),
                         bool(np.any(ref.jnt_stiffness[j] != 0)) if np.ndim(ref.jnt_stiffness) > 1
                         else bool(ref.jnt_stiffness[j] != 0))
                  for j, name in zip(ids, (x.name for x in mapped))}
    removed = dict(stripped)
    held = fixed + hold(mj, src, spec, ref, set(ids), dict(src.locked))
    owner = owners(ref, joint_bodies)
    n = d.n
    planar = d.arm.spatial is None
    payload = planar and any(pm.link == n - 1 for pm in d.arm.point_masses)
    scaled = {}
    for sb in spec.bodies[1:]:
        b = sb.id
        sb.mass, sb.ipos, sb.iquat = float(ref.body_mass[b]), ref.body_ipos[b].copy(), ref.body_iquat[b].copy()
        sb.inertia, sb.fullinertia[0], sb.explicitinertial = ref.body_inertia[b].copy(), math.nan, True
        i = owner[b]
        factor = 1.0
        if i >= 0 and (not planar or b == joint_bodies[i]):
            factor = s.link_mass_scale[i]
        elif payload and i == n - 1:
            factor = s.payload_scale
        if factor != 1.0:
            sb.mass, sb.inertia = sb.mass * factor, sb.inertia * factor
            scaled[sb.name or f"body {b}"] = factor
    welded = weld_payload(spec, ref, src, d, s, ids[-1])   # [simulation] payload_mass (derive.sim.mujoco.payload)
    drive = drives(d, values)
    extras = []
    own_mjcf = src.kind == "mjcf" and getattr(src, "own", False)
    if own_mjcf and any(sb.gravcomp for sb in spec.bodies[1:]):
        removed["bodies' gravity compensation (gravcomp; derive's chain has none)"] = sum(
            1 for sb in spec.bodies[1:] if sb.gravcomp)
        for sb in spec.bodies[1:]:
            sb.gravcomp = 0.0
    coulomb = np.array(s.coulomb_friction, dtype=float)
    for i, (sj, dr) in enumerate(zip(mapped, drive)):
        damping, frictionloss, armature, limited, spring = file_joint[sj.name]
        if friction == "file" and frictionloss:
            coulomb[i] = 0.0
        if friction == "off":
            damping, frictionloss, armature = dr.damping, 0.0, 0.0
            sj.limited, sj.stiffness = mj.mjtLimited.mjLIMITED_FALSE, np.zeros_like(sj.stiffness)
        else:
            extras += [f"{sj.name}: friction loss {frictionloss:g} N m (MuJoCo's dry friction)"] if frictionloss else []
            extras += [f"{sj.name}: joint limits [{sj.range[0]:g}, {sj.range[1]:g}]"] if limited else []
            extras += [f"{sj.name}: a spring (stiffness)"] if spring else []
            if damping != dr.damping:
                extras.append(f"{sj.name}: damping {damping:g} N m s/rad from the file, derive's bv = {dr.damping:g}")
            extras += [f"{sj.name}: armature {armature:g} kg m^2 from the file"] if armature and not own_mjcf else []
        sj.damping = [damping + s.viscous_friction[i], *([0.0] * (len(sj.damping) - 1))]  # no polynomial terms
        sj.frictionloss = frictionloss
        if own_mjcf:   # the file's armature is derive's rotor inertia (its default), not added to it
            if friction == "file" and armature != dr.armature:
                extras.append(f"{sj.name}: armature {dr.armature:g} kg m^2 (derive's rotor inertia), the file's "
                              f"{armature:g} replaced")
            armature = 0.0
        sj.armature = armature + dr.armature
        sj.actfrclimited = mj.mjtLimited.mjLIMITED_FALSE
        a = spec.add_actuator(name=f"derive_u{i + 1}", target=sj.name, trntype=mj.mjtTrn.mjTRN_JOINT)
        a.gaintype, a.biastype, a.dyntype = mj.mjtGain.mjGAIN_FIXED, mj.mjtBias.mjBIAS_AFFINE, mj.mjtDyn.mjDYN_NONE
        a.gainprm[0], a.biasprm[2], a.gear[0] = dr.gain, dr.bias, dr.gear   # MuJoCo: velocity = gear theta'
        a.ctrllimited = a.forcelimited = mj.mjtLimited.mjLIMITED_FALSE
    rep = {sym: v for (sym, _), v in zip(d.values, values)}
    g_base = np.array([float(x.xreplace(rep)) for x in chain.gravity])
    opt = spec.option
    opt.timestep = s.sample_time / s.substeps
    opt.integrator = mj.mjtIntegrator.mjINT_RK4
    opt.gravity = to_world @ g_base
    contacts = src.kind == "mjcf" and friction == "file" and s.mujoco_contacts and len(spec.geoms) > 0
    flags = mj.mjtDisableBit.mjDSBL_AUTORESET
    if not contacts:
        flags |= mj.mjtDisableBit.mjDSBL_CONTACT
    else:
        extras.append(f"contacts between the MJCF's {len(spec.geoms)} primitive geoms")
    if not (contacts or any(file_joint[j.name][1] or file_joint[j.name][3] for j in mapped)) or friction == "off":
        flags |= mj.mjtDisableBit.mjDSBL_CONSTRAINT
    opt.disableflags = int(opt.disableflags) | int(flags)
    spec.nuserdata = 2 + 3 * n   # the loop's: tag, n, dof addresses, tau_c, eps (templates/sim/mujoco_loop.c.jinja)
    spec.compiler.inertiafromgeom = mj.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    fused = spec.copy()
    fused.compiler.fusestatic = True
    with collected_warnings(mj) as said:
        try:
            model = fused.compile()
            used = fused
        except Exception:  # noqa: BLE001 - MuJoCo cannot fuse some degenerate inertias: keep the bodies apart
            spec.compiler.fusestatic = False
            model, used = _compile(mj, src, spec, "model with derive's edits"), spec
        xml = written_xml(used, src, coulomb, contacts)
        if not contacts and (len(used.geoms) or len(used.lights)):   # inert without contacts: not computed
            for item in [*used.geoms, *used.lights]:
                used.delete(item)
            model = _compile(mj, src, used, "model with derive's edits")
    removed.update({f"MuJoCo warned: {text}": 0 for text in dict.fromkeys(said)})
    if model.nv != n:
        raise fail(src, f"expected {n} degrees of freedom once the other joints are held, got {model.nv}")
    qadr = np.array([model.joint(j.name).qposadr[0] for j in mapped], dtype=np.int32)
    dadr = np.array([model.joint(j.name).dofadr[0] for j in mapped], dtype=np.int32)
    description = _describe(mj, src, d, s, friction, mapped, drive, held, removed, scaled, extras, payload,
                            opt.gravity, coulomb)
    description["notes"] += [welded] if welded else []
    return Compiled(model, qadr, dadr, coulomb, description, xml)


def written_xml(spec, src, coulomb, contacts: bool) -> str:
    """The model MuJoCo integrates as MJCF text (module docstring, step 7), with a comment saying what
    it is and what derive adds at run time ("" when MuJoCo cannot write it); without contacts its geoms
    and lights are kept for the viewer (the run leaves them out: they exert nothing, the inertias are
    explicit)."""
    try:
        text = spec.to_xml()
    except Exception:  # noqa: BLE001 - MuJoCo's writer refuses some models; the run does not need the text
        return ""
    shown = src.shown.replace("--", "- -")   # "--" may not stand inside an XML comment
    head = (f"<!-- generated by derive simulate (the MuJoCo plant) from {shown}; do not edit. The model MuJoCo "
            "integrated: derive's held joints fixed, its drives as actuators (ctrl = u + d)"
            + ("; derive's smooth Coulomb friction tau_c tanh(theta'/eps) is added at run time by derive's loop "
               "(mjcb_passive), not in this file" if any(coulomb) else "")
            + ("; contacts off: its geoms are drawn only (the run leaves them out)" if not contacts and
               len(spec.geoms) else "") + " -->\n")
    return head + text


def _describe(mj, src, d, s, friction, mapped, drive, held, removed, scaled, extras, payload, gravity,
              coulomb) -> dict:
    """The plant as the metrics file states it."""
    voltage = [a.actuation is Actuation.VOLTAGE for a in d.dynamics.chain.actuators]
    joints = []
    for i, (sj, dr, v) in enumerate(zip(mapped, drive, voltage)):
        joints.append({"derive": d.dynamics.chain.joints[i].name, "mujoco": sj.name,
                       "actuator": ("DC motor: gain Kt/R = %.6g, back-EMF bias -Kt Kv/R = %.6g, gear %.6g"
                                    % (dr.gain, dr.bias, dr.gear)) if v else "torque: gear %.6g" % dr.gear,
                       "armature": float(sj.armature), "damping": float(sj.damping[0]),
                       "frictionloss": float(sj.frictionloss)})
    notes = list(src.notes)
    notes += [what if what.startswith("MuJoCo warned") else f"removed from the file: {k} {what}"
              for what, k in removed.items()]
    if scaled:
        notes.append("mass and inertia scaled ([simulation] mismatch): "
                     + ", ".join(f"{name} x{f:g}" for name, f in scaled.items()))
    if s.payload_scale != 1.0 and not payload:
        notes.append(f"payload_scale {s.payload_scale:g} not applied: the arm has no point masses on its last "
                     "link (derive's plant does not apply it either)")
    if any(coulomb):
        widths = ", ".join(f"{e:g}" for e in coulomb_widths(s, len(mapped)))
        notes.append("[simulation] coulomb_friction as derive's smooth law tau_c tanh(theta'/eps), eps = "
                     f"[{widths}] rad/s (coulomb_smoothing), added to MuJoCo's passive forces (mjcb_passive) at every "
                     "RK4 stage")
    replaced = [f"{sj.name} ({c:g} N m)" for sj, c, kept in zip(mapped, s.coulomb_friction, coulomb) if c and not kept]
    if replaced:
        notes.append("[simulation] coulomb_friction not added where the file's friction loss is the joint's Coulomb "
                     "friction: " + ", ".join(replaced))
    return {"name": "mujoco", "engine": f"MuJoCo {mj.__version__}", "model": src.shown, "kind": src.kind,
            "integrator": "RK4", "timestep": s.sample_time / s.substeps, "steps_per_sample": s.substeps,
            "gravity": [float(x) for x in gravity], "friction": friction, "joints": joints, "held": held,
            "beyond_derive": extras, "notes": notes}
