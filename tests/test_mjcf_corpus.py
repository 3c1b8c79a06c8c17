"""Every arm of the MJCF corpus (tests/data/mjcf/menagerie: MuJoCo Menagerie arms, meshes stripped) read
by derive (derive.model.mjcf) and held against two other engines reading the same file, at 20 seeded
random states within the joint limits, to 1e-10 of each matrix's largest entry:

* MuJoCo itself (``mujoco.MjModel.from_xml_path``, not derive's reading of it): J(q) against
  ``mj_fullM`` (the MJCF's armature is derive's rotor inertia, so both hold it), the bias (Coriolis,
  centrifugal and gravity forces, eq. 12 without damping) against ``qfrc_bias`` and g(q) against
  ``qfrc_bias`` at rest, the joints derive holds at their held value (0) with no velocity (the chain
  rows of the whole model are then the reduced chain's);
* Pinocchio's MJCF loader (``pin.buildModelFromMJCF``, the held joints removed by
  ``buildReducedModel``): ``crba`` (with the model's armature), ``rnea(q, v, 0)`` and
  ``computeGeneralizedGravity``.

Gravity is the MJCF's, turned into the base body's frame (derive.model.mjcf.gravity_in_base), as
``derive init`` writes it."""
from __future__ import annotations

import functools
import json
import math
import shutil
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from derive.model.spec import arm_from_dict

from .corpus import CorpusArm, corpus_arms, dynamics_function, random_states

mujoco = pytest.importorskip("mujoco")

ARMS = corpus_arms("mjcf")
RTOL = 1e-10
STATES = 20
SEED = 35


def mapping(arm: CorpusArm, n: int = 1) -> dict:
    """The arm-file mapping of an MJCF corpus arm (torque actuation, the MJCF's gravity in the base frame)."""
    from derive.model.mjcf import gravity_in_base

    model = mujoco.MjModel.from_xml_path(str(arm.urdf))
    size, direction = gravity_in_base(model, arm.base)
    table = {"name": "corpus", "mjcf": str(arm.urdf), "base_body": arm.base, "tip_body": arm.tip,
             "gravity": size, "gravity_direction": list(direction), "actuation": "torque"}
    if arm.locked:
        table["locked"] = dict(arm.locked)
    return {"arm": table, "controller": {"T1": 0.0, "T2": 0.2, "w": [5.0] * n}}


@functools.lru_cache(maxsize=None)
def _numeric(arm: CorpusArm):
    """derive's arm, and J, bias, g of its dynamics as one numeric function of (q, v)."""
    from derive.errors import SpecError

    try:
        loaded = arm_from_dict(mapping(arm), arm.name)
    except SpecError as exc:   # the controller's w has one entry: the count tells n
        n = int(str(exc).split("array of ")[1].split(" ")[0])
        loaded = arm_from_dict(mapping(arm, n), arm.name)
    return loaded, dynamics_function(loaded)


def _states(loaded) -> list[tuple[np.ndarray, np.ndarray]]:
    return random_states(loaded, SEED, STATES)


def _close(name: str, where: str, ours: np.ndarray, theirs: np.ndarray) -> None:
    scale = max(np.max(np.abs(theirs)), 1e-300)
    assert np.max(np.abs(ours - theirs)) <= RTOL * scale, (
        f"{name} of {where}: |derive - reference| = {np.max(np.abs(ours - theirs)):.3g}, largest entry {scale:.3g}")


@pytest.mark.parametrize("arm", ARMS, ids=[a.name for a in ARMS])
def test_mjcf_arm_dynamics_match_mujoco(arm: CorpusArm) -> None:
    """J against mj_fullM, the bias against qfrc_bias, g against qfrc_bias at rest (module docstring)."""
    loaded, evaluate = _numeric(arm)
    model = mujoco.MjModel.from_xml_path(str(arm.urdf))
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    data = mujoco.MjData(model)
    dofs = [int(model.joint(j.name).dofadr[0]) for j in loaded.chain.joints]
    qadr = [int(model.joint(j.name).qposadr[0]) for j in loaded.chain.joints]
    assert [name for name, _ in loaded.chain.held] == sorted(
        model.joint(j).name for j in range(model.njnt) if model.joint(j).name not in {x.name for x in
                                                                                  loaded.chain.joints})
    for k, (q, v) in enumerate(_states(loaded)):
        data.qpos[:], data.qvel[:] = model.qpos0, 0.0
        data.qpos[qadr], data.qvel[dofs] = q, v
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, M)
        bias = data.qfrc_bias[dofs].copy()
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        J, b, g = evaluate(q, v)
        where = f"{arm.name}, state #{k}"
        _close("J", where, J, M[np.ix_(dofs, dofs)])
        _close("bias", where, b, bias)
        _close("g", where, g, data.qfrc_bias[dofs])


@pytest.mark.parametrize("arm", ARMS, ids=[a.name for a in ARMS])
def test_mjcf_arm_dynamics_match_pinocchio(arm: CorpusArm) -> None:
    """J against crba (with the armature), the bias against rnea(q, v, 0), g against Pinocchio's."""
    pin = pytest.importorskip("pinocchio")
    loaded, evaluate = _numeric(arm)
    full = pin.buildModelFromMJCF(str(arm.urdf))
    moving = {j.name for j in loaded.chain.joints}
    lock = [full.getJointId(name) for name in full.names[1:] if name not in moving]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    assert sorted(model.names[1:]) == sorted(moving)
    data = model.createData()
    order = [model.joints[model.getJointId(j.name)].idx_v for j in loaded.chain.joints]
    for k, (q, v) in enumerate(_states(loaded)):
        qp, vp = pin.neutral(model), np.zeros(model.nv)
        for i, j in enumerate(loaded.chain.joints):
            joint = model.joints[model.getJointId(j.name)]
            qp[joint.idx_q:joint.idx_q + joint.nq] = [math.cos(q[i]), math.sin(q[i])] if joint.nq == 2 else [q[i]]
            vp[joint.idx_v] = v[i]
        M = pin.crba(model, data, qp)
        M = (np.triu(M) + np.triu(M, 1).T)[np.ix_(order, order)]
        bias = pin.rnea(model, data, qp, vp, np.zeros(model.nv))[order]
        g = pin.computeGeneralizedGravity(model, data, qp)[order]
        J, b, gd = evaluate(q, v)
        where = f"{arm.name} (Pinocchio), state #{k}"
        _close("J", where, J, M)
        _close("bias", where, b, bias)
        _close("g", where, gd, g)


def test_mjcf_armature_damping_friction_and_limits_are_read() -> None:
    """The Sawyer's armature (1), damping (0.1) and frictionloss (0.3 large and medium joints, 0.1
    small) and its actuators' forcerange (80, 40, 9 N m) reach derive's arm as rotor inertia,
    viscous friction, the simulation's Coulomb friction and torque limits; its joint ranges as limits."""
    arm = next(a for a in ARMS if a.name == "menagerie_sawyer")
    loaded, _ = _numeric(arm)
    assert [m.rotor_inertia for m in loaded.motors] == [Fraction(1)] * 7
    assert [bv for bv, _ in loaded.joint_friction] == [Fraction(1, 10)] * 7
    assert loaded.simulation.coulomb_friction == (0.3, 0.3, 0.3, 0.3, 0.1, 0.1, 0.1)
    assert [j.limits.effort for j in loaded.chain.joints] == [80, 80, 40, 40, 9, 9, 9]
    assert (loaded.chain.joints[1].limits.lower, loaded.chain.joints[1].limits.upper) == (
        Fraction("-3.8095"), Fraction("2.2736"))


PIPELINE = [a for a in ARMS if a.pipeline == "test"]


@pytest.mark.parametrize("arm", PIPELINE, ids=[a.name for a in PIPELINE])
def test_mjcf_arm_through_init_show_check_and_mujoco(arm: CorpusArm, tmp_path: Path) -> None:
    """The cheap part of ``make corpus`` for one Menagerie arm: derive init on the MJCF, show, check
    (each exit 0, as benchmarks/corpus.py runs them), then simulate --plant mujoco (NPID and DOBC, 1 s)
    on that same MJCF: the plant is the file, its joints derive's, and no run fails."""
    sys.path.insert(0, str(Path(__file__).parents[1]))
    from benchmarks.corpus import _derive, run_command

    shutil.copy(arm.urdf, tmp_path / arm.file)
    toml = f"{arm.name}.toml"
    for argv in (["init", arm.file, "--base", arm.base, "--tip", arm.tip, "--name", arm.name, "--out", toml],
                 ["show", toml], ["check", toml],
                 ["simulate", toml, "--plant", "mujoco", "--duration", "1", "--controllers", "npid,dobc", "--out",
                  "sim", "--json", "m.json"]):
        code, _, _, text, _ = run_command(_derive(*argv), tmp_path, 600)
        assert code == 0, (argv[0], text[-1500:])
    metrics = json.loads((tmp_path / "m.json").read_text())
    plant = metrics["plant"]
    assert plant["name"] == "mujoco" and plant["kind"] == "mjcf" and plant["model"] == arm.file
    assert [j["mujoco"] for j in plant["joints"]] == [j["derive"] for j in plant["joints"]]
    assert set(metrics["controllers"]) == {"npid", "dobc"}
    assert all("failed" not in c for c in metrics["controllers"].values())
    assert (tmp_path / "sim" / "mujoco_model.xml").is_file()
