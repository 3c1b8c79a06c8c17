"""The ``[simulation]`` payload in MuJoCo's model: a body welded to the tip body (issue 38).

derive's plant adds J_p and G_p of a rigid payload on its last body (derive.sim.plant,
derive.dynamics.payload); MuJoCo's gets the payload as a body of its own, ``derive_payload``,
without a joint, a child of the body of the arm file's tip link (``[arm] tip_link``, or
``tip_body`` of an MJCF arm) with

    mass = payload_mass,  pos = payload_com (the tip link's frame),
    fullinertia = the inertia about the centre of mass in that frame

(derive.sim.plant.payload_values' mass, centre of mass and inertia before they are turned into
F_n), so the two plants place the payload each through its own frames: derive through
``Chain.tip`` (the tip link's frame in F_n), MuJoCo through its body tree. MuJoCo's compiler
fuses the welded body into the body the last joint moves (``fusestatic``). When the tip link is
not a body of the model MuJoCo integrates (a ``mujoco_model`` with other names, a planar or DH
arm), the payload is welded to the body of the last joint instead, at its centre of mass in F_n
(derive's last joint frame: that body's frame moved to the joint's anchor, derive.model.mjcf).
"""
from __future__ import annotations

import numpy as np

NAME = "derive_payload"


def _below(ref, body: int, above: int) -> bool:
    """``body`` is ``above`` or hangs below it in the compiled reference's tree."""
    while body not in (above, 0):
        body = int(ref.body_parentid[body])
    return body == above


def weld_payload(spec, ref, src, d, s, last_joint: int) -> str | None:
    """Add the payload of settings ``s`` to ``spec`` (an MjSpec whose compiled reference is ``ref``;
    ``src`` derive.sim.mujoco.source.MujocoSource; ``d`` the Derivation; ``last_joint`` the
    reference's id of derive's last joint); the sentence for the plant's notes, None without a payload."""
    from derive.model.payload import tip_to_body
    from derive.sim.plant import payload_inertia, payload_com, payload_note

    if s.payload_mass <= 0:
        return None
    com, inertia = np.array(payload_com(d, s), dtype=float), payload_inertia(d, s)
    last_body = int(ref.jnt_bodyid[last_joint])
    names = [ref.body(b).name for b in range(ref.nbody)]
    tip = src.tip if src.tip in names else None
    if tip is not None and _below(ref, names.index(tip), last_body):
        parent, where = spec.body(tip), f"welded to the tip body {tip!r} (fused into the body the last joint moves)"
    else:
        com, inertia = tip_to_body(d.dynamics.chain, com, inertia)
        com = com + np.asarray(ref.jnt_pos[last_joint], dtype=float)
        parent = spec.body(names[last_body])
        where = (f"welded to {names[last_body]!r}, the body of the last joint, at its centre of mass in derive's "
                 f"last joint frame (the tip {src.tip!r} is not a body below it in the model)" if src.tip else
                 f"welded to {names[last_body]!r}, the body of the last joint, at its centre of mass in derive's "
                 "last joint frame (the arm file names no tip link)")
    body = parent.add_body(name=NAME, pos=[float(x) for x in com])
    body.mass = float(s.payload_mass)
    body.ipos = [0.0, 0.0, 0.0]
    body.fullinertia = [float(inertia[0, 0]), float(inertia[1, 1]), float(inertia[2, 2]), float(inertia[0, 1]),
                        float(inertia[0, 2]), float(inertia[1, 2])]
    body.explicitinertial = True
    return f"{payload_note(d, s)}: a body {NAME!r} {where}"
