"""Issue 38: the ``[simulation]`` payload in every plant, never in the controller's model.

A rigid payload (``payload_mass`` kg at ``payload_com``, the tip link's frame) makes the true
plant J + J_p, G + G_p (eq. 12, derive.dynamics.payload). Checked here:

* derive's plant (derive.sim.plant.Plant.matrices) against Pinocchio with the payload added as a
  body, placed through Pinocchio's own frame of the tip link (the Panda: its tip panda_hand_tcp is
  two fixed joints and a 45-degree turn below panda_link7), and against Pinocchio's model of the
  paper's planar arm with the payload on its last body: J to 1e-10 of its largest entry, G to 1e-10
  relative at seeded states;
* the Python-stepped plant and the compiled loop (built with the payload's kernels) agree to 1e-9
  on the paper's arm and a URDF arm, and the payload moves the trajectory;
* MuJoCo (a body welded to the tip body) and derive's plant agree within
  tests/test_mujoco_plant.py's stated tolerance, friction off, for two URDF arms and an MJCF arm
  whose tip body hangs turned and offset below a joint with an anchor;
* the plant FMU's payload_mass and payload_com change its trajectory as derive's plant does (1e-12);
* bad payload input: one clear error naming the field, exit 2, nothing written.

The sweep's 1- and 2-worker byte identity with payload_mass and payload_com drawn is
tests/test_sweep.py's (its SWEEP varies both).
"""
from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.model.spec import load_arm, resolve_arm_path
from derive.sim.plant import Plant, payload_values, true_plant

DATA = Path(__file__).resolve().parent / "data" / "urdf"
RTOL = 1e-10
STATES = 12
PAYLOAD = {"payload_mass": 2.0, "payload_com": (0.03, -0.02, 0.06)}   # kg; m, tip link's frame


def _with_payload(arm, mass: float = PAYLOAD["payload_mass"], com=PAYLOAD["payload_com"], **more):
    return replace(arm, simulation=replace(arm.simulation, payload_mass=mass, payload_com=tuple(com), **more))


def _states(n: int, seed: int = 38):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.5, 1.5, (STATES, n)), rng.uniform(-2.0, 2.0, (STATES, n))


def _against_pinocchio(d, model, s) -> None:
    """derive's true J and G (Plant.matrices) against crba and rnea(q, v, 0) of ``model`` plus the
    drives' reflected inertia and damping (tests/pinplant.drives)."""
    pin = pytest.importorskip("pinocchio")
    from tests.pinplant import drives

    Ia, bv, emf = drives(d.arm)
    data = model.createData()
    q, dq = _states(d.n)
    J, G = Plant(d, true_plant(d, s)).matrices(q, dq)
    for k in range(STATES):
        M = pin.crba(model, data, q[k])
        M = np.triu(M) + np.triu(M, 1).T + np.diag(Ia)
        bias = pin.rnea(model, data, q[k], dq[k], np.zeros(d.n)) + (bv + emf) * dq[k]
        np.testing.assert_allclose(J[k], M, rtol=0, atol=RTOL * np.max(np.abs(M)), err_msg=f"J at state {k}")
        np.testing.assert_allclose(G[k], bias, rtol=RTOL, atol=RTOL * np.max(np.abs(bias)), err_msg=f"G at state {k}")


def test_eq12_panda_plant_with_a_payload_equals_pinocchio_with_the_payload_as_a_body_on_the_tip_frame():
    pin = pytest.importorskip("pinocchio")
    from tests.pinplant import urdf_model

    arm = _with_payload(load_arm(DATA / "panda.toml"))
    d = derive.derive(arm)
    assert d.dynamics.chain.tip is not None   # panda_hand_tcp is not F_7: the frame change is exercised
    model = urdf_model(DATA / "panda.urdf", moving=[j.name for j in d.dynamics.chain.joints])
    tip = model.frames[model.getFrameId("panda_hand_tcp")]
    assert tip.parentJoint == model.njoints - 1
    sphere = 0.4 * 2.0 * 0.05 ** 2 * np.eye(3)
    model.inertias[model.njoints - 1] += tip.placement.act(pin.Inertia(2.0, np.array(PAYLOAD["payload_com"]), sphere))
    _against_pinocchio(d, model, arm.simulation)
    # and the payload is really there: without it Pinocchio's model differs from the plant
    bare = urdf_model(DATA / "panda.urdf", moving=[j.name for j in d.dynamics.chain.joints])
    with pytest.raises(AssertionError):
        _against_pinocchio(d, bare, arm.simulation)


def test_eq12_planar_plant_with_a_payload_and_a_stated_inertia_equals_pinocchio(tmp_path):
    """The paper's arm with a ``[payload]`` table stating an inertia (its shape at payload_mass) and
    payload_com defaulting to the table's com: Pinocchio's chain model with that body added."""
    pin = pytest.importorskip("pinocchio")
    from tests.pinplant import chain_model

    text = resolve_arm_path(None).read_text()
    text = text[: text.index("[sweep]")] if "[sweep]" in text else text
    inertia = [[0.002, 0.0001, 0.0], [0.0001, 0.003, 0.0], [0.0, 0.0, 0.004]]
    path = tmp_path / "arm.toml"
    path.write_text(text + f"\n[payload]\nmass = 1.0\ncom = [0.02, 0.01, 0.0]\ninertia = {inertia}\n"
                    "\n[simulation]\npayload_mass = 0.4\npayload_scale = 1.0   # the arm file's tip mass: Pinocchio has it\n")
    arm = load_arm(path)
    d = derive.derive(arm)
    s = arm.simulation
    assert payload_values(d, s) == pytest.approx((0.4, 0.02, 0.01, 0.0, 0.0008, 0.00004, 0.0, 0.0012, 0.0, 0.0016),
                                                 rel=1e-15)
    payload = pin.Inertia(0.4, np.array([0.02, 0.01, 0.0]), 0.4 * np.array(inertia))
    _against_pinocchio(d, chain_model(arm, payload), s)


@pytest.mark.parametrize("source", [None, str(DATA / "double_pendulum.toml")], ids=["paper", "double_pendulum"])
def test_eq12_python_and_compiled_plants_agree_with_a_payload(source):
    from derive.sim.backends import Backend
    from derive.sim.compiled import build
    from derive.sim.simulate import run_compiled, run_many

    arm = load_arm(source)
    arm = _with_payload(arm, 0.3, (0.05, 0.02, 0.01), duration=4.0)
    d = derive.derive(arm)
    s = arm.simulation
    plant = true_plant(d, s)
    assert plant.has_payload and plant.changed["payload_m"] == (0.0, 0.3)
    loop = build(d, payload=True)
    compiled = {name: run_compiled(d, loop, plant, s, name) for name in ("npid", "dobc")}
    backend = Backend(d, "python")
    reference = run_many(d, backend, Plant(d, plant), s, ["npid", "dobc"])
    backend.close()
    bare = run_compiled(d, build(d), true_plant(d, replace(s, payload_mass=0.0)), replace(s, payload_mass=0.0), "npid")
    for name, c in compiled.items():
        p = reference[name]
        assert c.failure is None and p.failure is None
        np.testing.assert_allclose(c.theta, p.theta, rtol=0, atol=1e-9, err_msg=f"{name} theta")
        np.testing.assert_allclose(c.u, p.u, rtol=1e-9, atol=1e-9, err_msg=f"{name} u")
    assert np.max(np.abs(compiled["npid"].u - bare.u)) > 1e-3   # the payload is felt by the loop
    from derive.errors import DeriveError

    with pytest.raises(DeriveError, match=r"expected a loop built with the payload's J_p and G_p"):
        run_compiled(d, build(d), plant, s, "npid")


MJCF = """<mujoco model="tipped">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base">
      <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <body name="l1" pos="0 0 0.1">
        <joint name="j1" axis="0 0 1"/>
        <inertial pos="0.1 0 0.02" mass="1.2" fullinertia="0.01 0.012 0.008 0.001 0 0.0005"/>
        <body name="l2" pos="0.25 0 0.05" euler="0.2 0 0">
          <joint name="j2" axis="0 1 0" pos="0.02 0.01 0"/>
          <inertial pos="0.15 0 0" mass="0.8" diaginertia="0.002 0.01 0.011"/>
          <body name="hand" pos="0.3 0.02 -0.01" euler="0.3 -0.5 0.7">
            <inertial pos="0.02 0 0" mass="0.3" diaginertia="3e-4 4e-4 5e-4"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _mjcf_arm(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tipped.xml").write_text(MJCF)
    path = folder / "tipped.toml"
    com = ", ".join(map(repr, PAYLOAD["payload_com"]))
    path.write_text(f"""[arm]
name = "tipped"
mjcf = "tipped.xml"
base_body = "base"
tip_body = "hand"
gravity = 9.81
actuation = "torque"

[controller]
T1 = 0.0
T2 = 0.2
w = [0.5, 0.5]

[simulation]
sample_time = 0.002
substeps = 4
duration = 10.0
payload_mass = 1.5
payload_com = [{com}]
""")
    return path


@pytest.mark.parametrize("name", [pytest.param("panda", marks=pytest.mark.slow), "ur5", "mjcf"])   # Panda: make fuzz
def test_eq12_mujoco_with_the_payload_welded_to_the_tip_body_agrees_with_derives_plant(name, tmp_path):
    pytest.importorskip("mujoco")
    from derive.sim.plants import DerivedPlant, build, compare, select
    from tests.mujoco_arms import arm_copy
    from tests.test_mujoco_plant import tolerance

    if name == "mjcf":
        path = _mjcf_arm(tmp_path)
    else:
        path = arm_copy(tmp_path, name, {**PAYLOAD, "payload_com": list(PAYLOAD["payload_com"]), "duration": 10.0})
    arm = load_arm(path)
    d = derive.derive(arm)
    s = arm.simulation
    assert d.dynamics.chain.tip is not None   # the tip's frame is not F_n: both plants must turn the com
    mj = select(arm, "mujoco", "off")
    loop = build(d, sources=(mj, DerivedPlant()), payload=True)
    notes = mj.describe(d, s)["notes"]
    assert any(re.search(r"payload of [\d.]+ kg .* a body 'derive_payload' welded to the tip body", x) for x in notes)
    assert "payload" in DerivedPlant().describe(d, s)
    bare = DerivedPlant().run(d, build(d), replace(s, payload_mass=0.0), "npid")
    for controller in ("npid", "dobc"):
        a, b = mj.run(d, loop, s, controller), DerivedPlant().run(d, loop, s, controller)
        assert a.failure is None and b.failure is None, (a.failure, b.failure)
        diff = compare([a], [b], {"name": "derive"})
        assert diff["max_theta_difference"] <= tolerance(b, s), (name, controller, diff["controllers"])
    assert np.max(np.abs(b.u - bare.u)) > 1e-3   # the payload is felt: the agreement says something


def test_plant_fmu_payload_parameters_change_the_trajectory_as_derives_plant_does(tmp_path):
    from .fmuplant import built, fmu_run, plant_run

    arm = load_arm()
    d = derive.derive(arm)
    files = built(d, tmp_path)
    for key in ("payload_mass", "payload_com[1]", "payload_com[2]", "payload_com[3]"):
        assert files[1][key].causality == "parameter" and files[1][key].variability == "tunable", key
        assert float(files[1][key].start) == 0.0, key
    s, steps, u = arm.simulation, 400, np.array([1.0, -0.5])

    def fmu(mass: float, com, refused=None) -> np.ndarray:
        start = {"payload_mass": mass, **{f"payload_com[{i}]": c for i, c in zip((1, 2, 3), com)}}
        return fmu_run(files, s, steps, u, start, refused)

    def plant(mass: float, com) -> np.ndarray:
        return plant_run(d, replace(s, payload_mass=mass, payload_com=tuple(com)), steps, u)

    bare, loaded = fmu(0.0, (0.0, 0.0, 0.0)), fmu(0.8, (0.05, 0.02, 0.0), refused={"payload_mass": -1.0})
    np.testing.assert_allclose(bare, plant(0.0, (0.0, 0.0, 0.0)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(loaded, plant(0.8, (0.05, 0.02, 0.0)), rtol=0, atol=1e-12)
    assert np.max(np.abs(loaded - bare)) > 1e-3


BAD = [
    ("payload_mass = -1.0", r"simulation\.payload_mass: expected a finite number >= 0, got -1\.0"),
    ("payload_mass = nan", r"simulation\.payload_mass: expected a finite number >= 0, got nan"),
    ('payload_mass = "heavy"', r"simulation\.payload_mass: expected a finite number >= 0, got 'heavy'"),
    ("payload_com = [0.0, 0.1]", r"simulation\.payload_com: expected an array of 3 finite numbers \[m\].*got \[0\.0, "
     r"0\.1\]"),
    ("payload_com = [2.0, 0.0, 0.5]", r"simulation\.payload_com: expected a centre of mass within 2 m of the tip "
     r"link's origin \(\|payload_com\| <= 2 m\), got \[2\.0, 0\.0, 0\.5\] \(\|payload_com\| = 2\.06155 m\)"),
    ("payload_com = [0.0, inf, 0.0]", r"simulation\.payload_com: expected an array of 3 finite numbers"),
]


@pytest.mark.parametrize("line,message", BAD, ids=["negative", "nan", "text", "two numbers", "beyond 2 m", "inf"])
@pytest.mark.parametrize("command", ["simulate", "sweep"])
def test_bad_payload_is_one_clear_error_exit_2_nothing_written(tmp_path, capsys, line, message, command):
    text = resolve_arm_path(None).read_text()
    path = tmp_path / "arm.toml"
    assert not re.search(r"^\[simulation\]", text, flags=re.M)   # the paper's arm file has no [simulation] table
    path.write_text(text + f"\n[simulation]\n{line}\n")
    out = tmp_path / "out"
    assert main([command, str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert err.count("derive: error") == 1 and "Traceback" not in err
    assert not out.exists()


SWEEP_BAD = [
    ('payload_mass = { distribution = "uniform", low = -1.0, high = 5.0 }',
     r"sweep\.vary\.payload_mass\.low: expected a lower bound >= 0 \(payload_mass cannot be negative\), got -1\.0"),
    ('payload_com = { distribution = "normal", mean = 0.0, sd = 0.1 }',
     r"sweep\.vary\.payload_com\.low: expected bounds low and high on payload_com .*, got nothing"),
    ('payload_com = { distribution = "uniform", low = -1.5, high = 0.1 }',
     r"sweep\.vary\.payload_com\.low: expected bounds within 1\.155 m .*, got low = -1\.5, high = 0\.1 \(uniform\)"),
]


@pytest.mark.parametrize("line,message", SWEEP_BAD, ids=["negative mass", "unbounded com", "com beyond 2 m"])
def test_bad_payload_draws_are_one_clear_error_exit_2_nothing_written(tmp_path, capsys, line, message):
    text = resolve_arm_path(None).read_text()
    text = text[: text.index("[sweep]")] if "[sweep]" in text else text
    path = tmp_path / "arm.toml"
    path.write_text(text + f"\n[sweep]\nsamples = 2\n[sweep.vary]\n{line}\n")
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert err.count("derive: error") == 1 and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_sample_settings_draw_payload_com_per_component_and_the_worst_file_reruns_it():
    from derive.cli.sweep import simulation_table
    from derive.model.simspec import parse_simulation
    from derive.model.sweepspec import parse_sweep
    from derive.sim.sweep import sample_settings

    spec, problems = parse_sweep({"vary": {"payload_mass": {"distribution": "uniform", "low": 0.0, "high": 5.0},
                                           "payload_com": {"distribution": "uniform", "low": -0.1, "high": 0.1}}}, 2)
    assert problems == []
    base = derive.load_arm().simulation
    s, drawn = sample_settings(base, spec, 3, 2)
    assert 0 <= s.payload_mass <= 5 and s.payload_mass == drawn["payload_mass"]
    assert len(s.payload_com) == 3 and list(s.payload_com) == drawn["payload_com"]
    assert sample_settings(base, spec, 3, 2) == (s, drawn)   # (seed, index) alone
    again, problems = parse_simulation(simulation_table(s), 2)
    assert problems == [] and again == s
    assert "payload_mass" not in simulation_table(base) and "payload_com" not in simulation_table(base)
