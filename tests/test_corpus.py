"""Every arm of the URDF corpus (tests/data/urdf/corpus: vendor URDFs as they ship) read by
derive and compared with Pinocchio: J(q) against ``pin.crba``, the bias (Coriolis,
centrifugal and gravity forces, eq. 12 without damping) against ``pin.rnea(q, v, 0)``,
g(q) against ``pin.computeGeneralizedGravity``, to 1e-10 of each matrix's largest entry,
at 20 seeded random states within the joint limits. Pinocchio loads the same file
(``buildModelFromUrdf``) and holds the same joints (``buildReducedModel`` at locked's
values, a mimic at multiplier * master + offset, else 0: tests/corpus.py reads them from
the XML); gravity is -9.81 along the base link's z axis. An arm whose file has a real
defect is refused with one clear message naming it. The whole pipeline (init -> fmu) runs
on the arms marked ``pipeline = "test"`` here and on every arm in ``make corpus``."""
from __future__ import annotations

import functools
import math
import shutil
import sys
from fractions import Fraction
from pathlib import Path

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from derive.cli import main
from derive.model.inertia_repair import nearest_physical
from derive.model.fields import Reader
from derive.model.spec import SPATIAL_DOWN, arm_from_dict, gravity_parameter, unit_direction
from derive.model.urdf import urdf_chain

from .corpus import (INERTIA_KEYS, CorpusArm, arm_mapping, corpus_arms, dynamics_function, held_values, random_states,
                     urdf_with_inertias)

pin = pytest.importorskip("pinocchio")

ARMS = corpus_arms()
RTOL = 1e-10
STATES = 20
SEED = 19


def _param(arm: CorpusArm):
    marks = [pytest.mark.slow] if arm.slow_load else []
    return pytest.param(arm, id=arm.name, marks=marks)


@functools.lru_cache(maxsize=None)
def _numeric(arm: CorpusArm):
    """derive's arm, and J, bias, g of its dynamics as one numeric function of (q, v)."""
    n = _count(arm)
    loaded = arm_from_dict(arm_mapping(arm, n), f"corpus {arm.name}", arm.urdf.parent)
    return loaded, dynamics_function(loaded)


def _count(arm: CorpusArm) -> int:
    """The number of chain joints derive finds."""
    r = Reader()
    found = urdf_chain(r, arm_mapping(arm)["arm"], arm.urdf.parent, gravity_parameter(Fraction(981, 100)),
                       unit_direction(SPATIAL_DOWN))
    assert found is not None, r.problems
    return found.chain.n


def _pinocchio(arm: CorpusArm, loaded, tmp_path: Path):
    """The reduced Pinocchio model of the same chain, its data and the q of each name."""
    urdf = arm.urdf
    if arm.repair:
        repaired = {}
        for link in ET.parse(urdf).getroot().findall("link"):
            node = link.find("inertial/inertia")
            if node is None or not any(f"link {link.get('name')!r}: inertia repaired" in x for x in loaded.chain.notes):
                continue
            e = [float(node.get(k, 0.0)) for k in INERTIA_KEYS]
            I = [[e[0], e[1], e[2]], [e[1], e[3], e[4]], [e[2], e[4], e[5]]]
            repaired[link.get("name")] = nearest_physical(I).entries
        assert repaired, "a repaired arm repairs at least one link"
        urdf = urdf_with_inertias(arm, repaired, tmp_path)
    model = pin.buildModelFromUrdf(str(urdf))
    moving = [j.name for j in loaded.chain.joints]
    held = held_values(arm, moving)
    q0 = pin.neutral(model)
    lock = []
    for name, value in held.items():
        jid = model.getJointId(name)
        lock.append(jid)
        joint = model.joints[jid]
        q0[joint.idx_q:joint.idx_q + joint.nq] = [math.cos(value), math.sin(value)] if joint.nq == 2 else [value]
    reduced = pin.buildReducedModel(model, lock, q0) if lock else model
    assert sorted(reduced.names[1:]) == sorted(moving), (list(reduced.names), moving)
    data = reduced.createData()
    q_ref = pin.neutral(reduced)
    pin.framesForwardKinematics(reduced, data, q_ref)
    R = data.oMf[reduced.getFrameId(arm.base)].rotation
    reduced.gravity.linear = R @ np.array([0.0, 0.0, -9.81])
    return reduced, reduced.createData()


def _states(loaded) -> list[tuple[np.ndarray, np.ndarray]]:
    return random_states(loaded, SEED, STATES)


def _to_pin(model, loaded, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
    qp, vp, order = pin.neutral(model), np.zeros(model.nv), []
    for k, j in enumerate(loaded.chain.joints):
        joint = model.joints[model.getJointId(j.name)]
        qp[joint.idx_q:joint.idx_q + joint.nq] = [math.cos(q[k]), math.sin(q[k])] if joint.nq == 2 else [q[k]]
        vp[joint.idx_v] = v[k]
        order.append(joint.idx_v)
    return qp, vp, order


@pytest.mark.parametrize("arm", [_param(a) for a in ARMS if a.expect == "pass"])
def test_corpus_arm_dynamics_match_pinocchio(arm: CorpusArm, tmp_path: Path) -> None:
    """J (eq. 12) against crba, the bias against rnea(q, v, 0), g against Pinocchio's."""
    loaded, evaluate = _numeric(arm)
    model, data = _pinocchio(arm, loaded, tmp_path)
    for k, (q, v) in enumerate(_states(loaded)):
        qp, vp, order = _to_pin(model, loaded, q, v)
        M = pin.crba(model, data, qp)
        M = (np.triu(M) + np.triu(M, 1).T)[np.ix_(order, order)]
        bias = pin.rnea(model, data, qp, vp, np.zeros(model.nv))[order]
        g = pin.computeGeneralizedGravity(model, data, qp)[order]
        J, b, gd = evaluate(q, v)
        where = f"{arm.name}, state #{k}: q = {np.array2string(q, precision=4)}"
        for name, ours, theirs in (("J", J, M), ("bias", b, bias), ("g", gd, g)):
            scale = max(np.max(np.abs(theirs)), 1e-300)
            assert np.max(np.abs(ours - theirs)) <= RTOL * scale, (
                f"{name} of {where}: |derive - pinocchio| = {np.max(np.abs(ours - theirs)):.3g}, "
                f"largest entry {scale:.3g}")


@pytest.mark.parametrize("arm", [_param(a) for a in ARMS if a.expect == "refuse"])
def test_corpus_arm_with_a_real_defect_is_refused_by_name(arm: CorpusArm, tmp_path: Path, capsys) -> None:
    """derive init gives one clear refusal naming the defect (exit 2, nothing written)."""
    shutil.copy(arm.urdf, tmp_path / arm.file)
    code = main(["init", str(tmp_path / arm.file), "--base", arm.base, "--tip", arm.tip, *arm.init_options])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("derive: error: ") and arm.refusal in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [arm.file]


def test_the_corpus_has_what_the_issue_asks() -> None:
    """At least 12 vendor arms; the shapes asked for are there (read from the files)."""
    files = {a.file for a in ARMS}
    assert len(files) >= 12
    types, mimic, dynamics = set(), False, False
    for f in files:
        root = ET.parse(Path(ARMS[0].urdf.parent / f)).getroot()
        for j in root.findall("joint"):
            types.add(j.get("type"))
            mimic |= j.find("mimic") is not None
            dynamics |= j.find("dynamics") is not None
    assert {"revolute", "continuous", "prismatic"} <= types and mimic and dynamics
    assert any(a.expect == "refuse" for a in ARMS) and any(a.pipeline == "test" for a in ARMS)


PIPELINE = [a for a in ARMS if a.pipeline == "test"]


@pytest.fixture(scope="module", params=PIPELINE, ids=[a.name for a in PIPELINE])
def pipeline(request, tmp_path_factory):
    """init -> show -> check -> generate (C and Python self-tests) -> simulate -> fmu --plant
    on one arm, as benchmarks/corpus.py runs it (``make corpus``: every arm)."""
    sys.path.insert(0, str(Path(__file__).parents[1]))
    from benchmarks.corpus import run_arm

    arm = request.param
    folder = tmp_path_factory.mktemp(arm.name)
    shutil.copy(arm.urdf, folder / arm.file)
    return run_arm(arm, folder, timeout=600)


def test_corpus_arm_goes_through_every_command(pipeline) -> None:
    """Every command exits 0, the C self-tests pass and the Python module checks out."""
    assert [c.command for c in pipeline.commands] == ["init", "show", "check", "generate", "selftest-c",
                                                      "selftest-python", "simulate", "fmu --plant", "limits truth"]
    failed = {c.command: c.detail for c in pipeline.commands if not c.ok}
    assert not failed, failed


def test_corpus_arm_simulates_with_the_starter_files_own_settings(pipeline) -> None:
    step = next(c for c in pipeline.commands if c.command == "simulate")
    assert step.ok, step.detail
