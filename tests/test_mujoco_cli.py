"""Issue 21 from the command line and through the plant interface: ``derive simulate --plant
mujoco`` and ``--compare``, ``derive sweep --plant mujoco``, an MJCF instead of the URDF, held
joints, the Python-stepped loop, and bad input (one clear error, exit 2, nothing written).

Tolerances are those of tests/test_mujoco_plant.py (its module docstring): TOL plus the part
MuJoCo's principal-axis inertias allow, PARAM_REL max|theta''| T^2 / 2.
"""
from __future__ import annotations

import re

import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from derive.cli import main
from derive.control.pipeline import derive
from derive.errors import DeriveError
from derive.model.spec import ARMS_DIR, load_arm
from derive.sim.plants import DerivedPlant, build, compare, select
from tests.mujoco_arms import DATA, arm_copy
from tests.test_mujoco_plant import tolerance

ROOT = Path(__file__).resolve().parent.parent
COMMITTED = ROOT / "generated" / "glasgow_2link" / "sim" / "metrics.json"


def glasgow_file(folder: Path, model: str | Path) -> Path:
    """The packaged default arm with ``[simulation] mujoco_model`` (its own URDF, tests/data)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "glasgow_2link.toml"
    path.write_text((ARMS_DIR / "glasgow_2link.toml").read_text() + f'\n[simulation]\nmujoco_model = "{model}"\n')
    return path


def test_default_arm_from_its_own_urdf_reproduces_the_committed_metrics(tmp_path):
    """The default 2-link arm integrated by MuJoCo from its own URDF (tests/data/urdf/glasgow_2link.urdf)
    writes the committed generated/glasgow_2link/sim/metrics.json again within the stated tolerance
    (at its 7 significant digits), names the plant, and --compare reports derive's plant within it."""
    arm = glasgow_file(tmp_path, DATA / "glasgow_2link.urdf")
    out, js = tmp_path / "out", tmp_path / "m.json"
    assert main(["simulate", str(arm), "--plant", "mujoco", "--compare", "--out", str(out), "--json", str(js)]) == 0
    got, want = json.loads(js.read_text()), json.loads(COMMITTED.read_text())
    assert set(got["controllers"]) == set(want["controllers"])
    for name, entry in want["controllers"].items():
        for i, (a, b) in enumerate(zip(got["controllers"][name]["links"], entry["links"])):
            for key, value in b.items():
                assert math.isclose(a[key], value, rel_tol=1e-6, abs_tol=1e-8), (name, i + 1, key, a[key], value)
    plant = got["plant"]
    assert plant["name"] == "mujoco" and plant["kind"] == "urdf" and plant["integrator"] == "RK4"
    assert [(j["derive"], j["mujoco"]) for j in plant["joints"]] == [("joint1", "joint1"), ("joint2", "joint2")]
    assert any("tip x1.2" in note for note in plant["notes"]), plant["notes"]   # payload_scale on the tip body
    assert got["comparison"]["against"]["name"] == "derive"
    assert got["comparison"]["max_theta_difference"] <= 1e-9 + 1e-12 * 100 * 30 ** 2 / 2
    assert {"link1.png", "link2.png", "tracking_error.png", "plant_difference.png", "metrics.md"} <= {
        p.name for p in out.iterdir()}
    md = (out / "metrics.md").read_text()
    assert "(compiled backend, mujoco plant)" in md and "| joint1 | joint1 | DC motor" in md and "minus derive" in md


def test_derive_plant_is_named_too(tmp_path):
    """Without --plant the metrics name derive's plant and its RK4 step."""
    js = tmp_path / "m.json"
    assert main(["simulate", "--controllers", "npid", "--duration", "0.5", "--out", str(tmp_path / "o"),
                 "--json", str(js)]) == 0
    plant = json.loads(js.read_text())["plant"]
    assert plant["name"] == "derive" and plant["timestep"] == 0.0005 and plant["stiffest_mode"]["stable"]


SWEEP = """
[sweep]
samples = 8
seed = 3
controllers = ["mpc", "dobc", "npid"]
duration = 2.0

[sweep.vary]
link_mass = { distribution = "uniform", low = 0.8, high = 1.2 }
coulomb_friction = { distribution = "uniform", low = 0.5, high = 2.0 }
viscous_friction = { distribution = "uniform", low = 0.5, high = 2.0 }
disturbance = { distribution = "uniform", low = -0.5, high = 0.5 }
"""


def test_sweep_on_mujoco_is_the_same_for_one_and_two_workers_and_matches_derives(tmp_path):
    """8 samples on MuJoCo: the same sweep.json with 1 and 2 workers and on a Dask cluster (two
    threads of this process: MuJoCo runs concurrently); the mismatch drawn (link masses and
    inertias, friction, disturbance) applies to MuJoCo's model as to derive's plant, so the
    percentiles agree with derive's sweep to its 6 digits."""
    from distributed import LocalCluster

    arm = arm_copy(tmp_path, "double_pendulum", extra=SWEEP)
    texts = {}
    mujoco = ["--plant", "mujoco", "--mujoco-friction", "off"]
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        for label, options in (("one", [*mujoco, "--workers", "1"]), ("two", [*mujoco, "--workers", "2"]),
                               ("dask", [*mujoco, "--dask", cluster.scheduler_address]), ("derive", ["--workers", "1"])):
            js = tmp_path / f"{label}.json"
            assert main(["sweep", str(arm), "--out", str(tmp_path / label), "--json", str(js), *options]) == 0
            texts[label] = js.read_text()
    assert texts["one"] == texts["two"] == texts["dask"]
    mj, dv = json.loads(texts["one"]), json.loads(texts["derive"])
    assert mj["plant"]["name"] == "mujoco" and dv["plant"]["name"] == "derive"

    def numbers(x):
        if isinstance(x, dict):
            return [v for k in sorted(x) for v in numbers(x[k])]
        if isinstance(x, list):
            return [v for item in x for v in numbers(item)]
        return [x] if isinstance(x, float) else []
    a, b = numbers(mj["results"]), numbers(dv["results"])
    assert len(a) == len(b) > 100 and all(math.isclose(x, y, rel_tol=2e-6, abs_tol=1e-12) for x, y in zip(a, b))
    assert "--plant mujoco" in (tmp_path / "one" / "summary.md").read_text()


MJCF = """<mujoco model="pendulum">
  <compiler angle="radian"/>
  <asset><mesh name="shell" file="meshes/shell.stl"/></asset>
  <worldbody>
    <body name="base_link">
      <body name="link1" pos="0 0 0">
        <joint name="{j1}" type="hinge" axis="1 0 0" damping="0.05"/>
        <inertial pos="0 0 0.1" mass="1" diaginertia="0.01 0.01 0.001"/>
        <geom type="mesh" mesh="shell"/>
        <geom type="capsule" size="0.02" fromto="0 0 0 0 0 0.2"/>
        <body name="link2" pos="0 0 0.2">
          <joint name="{j2}" type="{kind}" axis="1 0 0" damping="0.3"/>
          <inertial pos="0 0 0.1" mass="0.5" diaginertia="0.005 0.005 0.0005"/>
          <geom type="mesh" mesh="shell"/>
        </body>
      </body>
      {sibling}
    </body>
  </worldbody>
  <actuator><position joint="{j1}" kp="10"/></actuator>
  <sensor><jointpos joint="{j1}"/></sensor>
</mujoco>
"""


def _mjcf(folder: Path, j1="joint1", j2="joint2", kind="hinge", sibling="", extra="") -> Path:
    arm = arm_copy(folder, "double_pendulum", extra='mujoco_model = "pendulum.xml"\n' + extra)
    (folder / "pendulum.xml").write_text(MJCF.format(j1=j1, j2=j2, kind=kind, sibling=sibling))
    return arm


def test_an_mjcf_is_read_without_its_meshes_and_its_own_actuators(tmp_path):
    """[simulation] mujoco_model names an MJCF (mesh files absent, a position servo and a sensor of
    its own): MuJoCo integrates it with derive's drives, its meshes, actuator and sensor removed
    (said in the description), its damping kept (friction "file"), and a pendulum of its numbers
    follows derive's plant of the same numbers within the stated tolerance when derive's damping is
    the MJCF's (friction "off" sets derive's). Contacts only when [simulation] mujoco_contacts asks."""
    plain = load_arm(_mjcf(tmp_path / "plain"))
    assert not any("contacts" in x for x in select(plain, "mujoco", "file").describe(derive(plain), plain.simulation)[
        "beyond_derive"])
    arm = load_arm(_mjcf(tmp_path, extra="mujoco_contacts = true\n"))
    d = derive(arm)
    mj = select(arm, "mujoco", "file")
    desc = mj.describe(d, arm.simulation)
    assert desc["kind"] == "mjcf" and desc["model"] == "pendulum.xml"
    assert any("1 actuators" in n for n in desc["notes"]) and any("2 mesh geoms" in n for n in desc["notes"])
    assert [j["damping"] for j in desc["joints"]] == pytest.approx([0.05 + 0.01, 0.3 + 0.002])
    assert "contacts between the MJCF's 1 primitive geoms" in desc["beyond_derive"]   # it asks for them
    s = replace(arm.simulation, duration=3.0)
    loop = build(d, sources=(mj, DerivedPlant()))
    a, b = mj.run(d, loop, s, "npid"), DerivedPlant().run(d, loop, s, "npid")
    assert a.failure is None and np.max(np.abs(b.theta)) > 0.5
    # the vendored pendulum's inertias differ from this MJCF's: the plants differ, and say by how much
    assert compare([a], [b], {})["max_theta_difference"] > 1e-3


def plants_agree(arm, controllers, expect=None) -> None:
    """``arm`` on MuJoCo (friction off) and on derive's plant: each controller tracks (joint 1 moves
    more than 0.5 rad, no failure) and the two stay within the stated tolerance; ``expect(d, mj)``
    checks the MuJoCo plant first."""
    d = derive(arm)
    mj = select(arm, "mujoco", "off")
    if expect is not None:
        expect(d, mj)
    loop = build(d, sources=(mj, DerivedPlant()))
    for name in controllers:
        a, b = mj.run(d, loop, arm.simulation, name), DerivedPlant().run(d, loop, arm.simulation, name)
        assert a.failure is None and np.max(np.abs(b.theta)) > 0.5, name
        assert compare([a], [b], {})["max_theta_difference"] <= tolerance(b, arm.simulation), name


@pytest.mark.parametrize("name, tip, held, kept", [
    ("double_pendulum", "link2", {"joint2": "1.5707963267948966"}, 1),   # a hinge at pi/2 (derive keeps it exact)
    ("synthetic", "tool", {"slide": "0.05"}, 3),                          # a slide at 5 cm
])
def test_held_joints_are_fixed_where_derive_holds_them(tmp_path, name, tip, held, kept):
    """A joint of the chain held at a non-zero value (arm.locked): MuJoCo's model fixes its body
    there (the joint's motion moves the body's frame), so the remaining chain follows derive's
    plant within the stated tolerance."""
    from derive.model.simspec import default_settings

    friction = list(default_settings(kept).coulomb_friction)   # of the joints left (tests/mujoco_arms.py)
    text = arm_copy(tmp_path, name, {"duration": 3.0, "coulomb_friction": friction}).read_text()
    text = text.replace(f'tip_link = "{tip}"', f'tip_link = "{tip}"\nlocked = {{ '
                        + ", ".join(f"{k} = {v}" for k, v in held.items()) + " }")
    head, *motors = text.split("[[motor]]")
    motors[-1], rest = motors[-1].split("[controller]")
    w = re.search(r"^w = \[([^,\]]*)", rest, flags=re.M).group(1)
    rest = re.sub(r"^w = \[[^\]]*\]", "w = [" + ", ".join([w] * kept) + "]", rest, flags=re.M)
    path = tmp_path / "held.toml"
    path.write_text(head + "[[motor]]" + "[[motor]]".join(motors[:kept]) + "\n[controller]" + rest)
    arm = load_arm(path)
    assert arm.n == kept

    def expect(d, mj):
        assert mj.describe(d, arm.simulation)["held"] == [f"{k} at {float(v):g}" for k, v in held.items()]
    plants_agree(arm, ("mpc", "npid"), expect)


def test_python_stepped_loop_runs_mujoco_like_the_compiled_one(tmp_path):
    """--backend python: the generated Python module stepped from Python, MuJoCo stepped through its
    bindings (the Coulomb friction through a Python passive callback), gives the compiled run."""
    from derive.sim.backends import Backend
    from derive.sim.simulate import run_many

    arm = load_arm(arm_copy(tmp_path, "double_pendulum", {"duration": 1.0}))
    d = derive(arm)
    mj = select(arm, "mujoco", "file")
    s = arm.simulation
    backend = Backend(d, "python")
    try:
        stepped = run_many(d, backend, mj.stepped(d, s), s, ["mpc", "dobc"])
    finally:
        backend.close()
    loop = build(d, sources=(mj,))
    for name, tr in stepped.items():
        assert np.max(np.abs(tr.theta - mj.run(d, loop, s, name).theta)) <= 1e-9, name
    select(arm, "mujoco").model(d, replace(s, duration=2.0))   # MuJoCo still compiles models afterwards


def _fails(tmp_path, capsys, argv, *words):
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out), "--json", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("derive: error:") == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, (word, err)
    assert not out.exists() and not (tmp_path / "m.json").exists()


@pytest.mark.parametrize("case, words", [
    ({"j1": "joint_1"}, ["expected a MuJoCo joint named 'joint1'", "did you mean 'joint_1'", "pendulum.xml"]),
    ({"kind": "slide"}, ["joint 'joint2'", "to be a MuJoCo hinge joint", "got a slide joint"]),
    ({"j2": "joint2_", "sibling": '<body name="side"><joint name="joint2" axis="1 0 0"/>'
      '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body>'}, ["below joint 'joint1'", "another branch"]),
])
def test_an_mjcf_whose_joints_do_not_match_is_one_error(tmp_path, capsys, case, words):
    """Issue 21, bad input: derive's joints are mapped onto MuJoCo's by name, type and order."""
    arm = _mjcf(tmp_path, **case)
    _fails(tmp_path, capsys, ["simulate", str(arm), "--plant", "mujoco"], *words)


@pytest.mark.parametrize("command", ("simulate", "sweep"))
def test_missing_model_file_is_one_error(tmp_path, capsys, command):
    arm = arm_copy(tmp_path, "double_pendulum", extra='mujoco_model = "nowhere/arm.xml"\n' + (
        SWEEP if command == "sweep" else ""))
    _fails(tmp_path, capsys, [command, str(arm), "--plant", "mujoco"], "simulation.mujoco_model", "no such file")


def test_hostile_or_foreign_model_files_are_one_error(tmp_path, capsys):
    arm = arm_copy(tmp_path, "double_pendulum", extra='mujoco_model = "bomb.xml"\n')
    (tmp_path / "bomb.xml").write_text('<?xml version="1.0"?><!DOCTYPE m [<!ENTITY a "aaaa">]><mujoco>&a;</mujoco>')
    _fails(tmp_path, capsys, ["simulate", str(arm), "--plant", "mujoco"], "without a DTD")
    (tmp_path / "bomb.xml").write_text("<sdf/>")
    _fails(tmp_path, capsys, ["simulate", str(arm), "--plant", "mujoco"], "root element <sdf>")


def test_a_planar_arm_without_a_model_file_is_one_error(tmp_path, capsys):
    _fails(tmp_path, capsys, ["simulate", "--plant", "mujoco"], "[simulation] mujoco_model", "planar")


@pytest.mark.parametrize("command", ("simulate", "sweep"))
def test_mujoco_not_installed_is_one_error(tmp_path, capsys, monkeypatch, command):
    """Without the mujoco package (its import fails) --plant mujoco says how to install it."""
    monkeypatch.setitem(sys.modules, "mujoco", None)
    arm = arm_copy(tmp_path, "double_pendulum", extra=SWEEP if command == "sweep" else "")
    _fails(tmp_path, capsys, [command, str(arm), "--plant", "mujoco"], "pip install 'derive[mujoco]'")
    with pytest.raises(DeriveError, match="expected the mujoco package"):
        select(load_arm(arm), "mujoco")


def test_an_mjcf_body_whose_inertia_comes_from_a_mesh_is_one_error(tmp_path, capsys):
    """derive reads no mesh file: a body that takes its mass from its mesh must give an <inertial>."""
    arm = _mjcf(tmp_path)
    xml = (tmp_path / "pendulum.xml").read_text()
    (tmp_path / "pendulum.xml").write_text(xml.replace('<inertial pos="0 0 0.1" mass="1" diaginertia="0.01 0.01 0.001"/>',
                                                       ""))
    _fails(tmp_path, capsys, ["simulate", str(arm), "--plant", "mujoco"], "body 'link1'", "(an <inertial>)",
           "mesh geom")


BAD_MJCF = {
    "malformed": ("<mujoco><worldbody>", "expected well-formed XML"),
    "include": ('<mujoco><include file="other.xml"/></mujoco>', "<include file='other.xml'> in pendulum.xml: "
                "expected a readable MJCF file"),
    "unphysical": (MJCF.format(j1="joint1", j2="joint2", kind="hinge", sibling="").replace(
        'diaginertia="0.01 0.01 0.001"', 'diaginertia="0.01 0.001 0.1"'), "MuJoCo could not compile the file"),
    "held after moving": (MJCF.format(j1="joint1", j2="joint2", kind="hinge", sibling="").replace(
        '<joint name="joint2" type="hinge" axis="1 0 0" damping="0.3"/>',
        '<joint name="joint2" type="hinge" axis="1 0 0" damping="0.3"/><joint name="extra" type="ball"/>'),
        "expected the held joints of body 'link2' before its moving ones"),
    "locked ball": (MJCF.format(j1="joint1", j2="joint2", kind="hinge", sibling=(
        '<body name="wrist"><joint name="joint3" type="ball"/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
        '</body>')), "arm.locked.joint3 = 0.5, got a ball joint"),
}


@pytest.mark.parametrize("case", sorted(BAD_MJCF))
def test_bad_mjcf_is_one_error(tmp_path, capsys, case):
    """Malformed XML, a missing <include>, an inertia MuJoCo refuses, a ball joint held after a moving one in
    the same body (a hinge held at 0 there is removed exactly), a ball joint held at a value: one clear
    error each, exit 2, nothing written."""
    text, words = BAD_MJCF[case]
    arm = arm_copy(tmp_path, "double_pendulum", extra='mujoco_model = "pendulum.xml"\n')
    if case == "locked ball":
        arm.write_text(arm.read_text().replace('tip_link = "link2"', 'tip_link = "link2"\nlocked = { joint3 = 0.5 }'))
        (tmp_path / "double_pendulum.urdf").write_text((tmp_path / "double_pendulum.urdf").read_text().replace(
            "</robot>", '<link name="wrist"/><joint name="joint3" type="revolute"><parent link="base_link"/>'
            '<child link="wrist"/><limit effort="1" velocity="1"/></joint></robot>'))
    (tmp_path / "pendulum.xml").write_text(text)
    _fails(tmp_path, capsys, ["simulate", str(arm), "--plant", "mujoco"], words)


def test_unknown_plant_and_friction_mode_are_errors():
    arm = load_arm(None)
    with pytest.raises(DeriveError, match="--plant: expected one of derive, mujoco, got 'bullet'"):
        select(arm, "bullet")
    with pytest.raises(DeriveError, match="--mujoco-friction: expected one of file, off, got 'some'"):
        select(load_arm(DATA / "double_pendulum.toml"), "mujoco", "some")


def test_simulate_refuses_when_rk4_is_unstable_in_the_stiffest_mode_and_warns_under_force(tmp_path, capsys):
    """The condition of the stated tolerance, checked for the user: the double pendulum's light second
    joint with 0.05 N m of smooth Coulomb friction at 4 RK4 steps per 2 ms sample. The trajectories
    would be wrong: refused before simulating (exit 2, nothing written) unless --force."""
    arm = arm_copy(tmp_path, "double_pendulum", {"duration": 0.2, "coulomb_friction": [0.05, 0.05]})
    js = tmp_path / "m.json"
    argv = ["simulate", str(arm), "--controllers", "npid", "--out", str(tmp_path / "o"), "--json", str(js)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("derive: error: simulation.substeps of double_pendulum = 4, derive's plant: the plant's "
                          "stiffest mode") and "or pass --force" in err and "Traceback" not in err, err
    assert not (tmp_path / "o").exists() and not js.exists()
    assert main([*argv, "--force"]) == 0
    err = capsys.readouterr().err
    stiff = json.loads(js.read_text())["plant"]["stiffest_mode"]
    assert not stiff["stable"] and stiff["substeps"] > 4
    assert "derive: warning: the plant's stiffest mode" in err and f"substeps to at least {stiff['substeps']}" in err
    fixed = arm.read_text().replace("substeps = 4", f"substeps = {stiff['substeps']}")
    arm.write_text(fixed)
    assert main(argv[:-2]) == 0 and "stiffest mode" not in capsys.readouterr().err


def test_geared_dc_motors_with_rotor_inertia_are_the_same_in_both_plants(tmp_path):
    """The DC motor behind a gear (tau = gr Kt (u - gr Kv theta')/R, eq. 11-12) as MuJoCo's general
    actuator and gr^2 Jm as armature: the default arm with gear ratios 3 and 5 and rotor inertias
    follows derive's plant within the stated tolerance (friction off), the [simulation] factors
    on the motor constants applied to both."""
    text = (ARMS_DIR / "glasgow_2link.toml").read_text()
    text = text.replace("gear_ratio = 1.0         # direct drive (section 5.1)", "gear_ratio = 3.0")
    text = text.replace("rotor_inertia = 0.0      # kg m^2, not given", "rotor_inertia = 2e-5")
    text = text.replace("resistance = 5.0\ngear_ratio = 1.0\nrotor_inertia = 0.0", "resistance = 5.0\ngear_ratio = 5.0\n"
                        "rotor_inertia = 1e-5")
    path = tmp_path / "geared.toml"
    path.write_text(text + f'\n[simulation]\nmujoco_model = "{DATA / "glasgow_2link.urdf"}"\nduration = 10.0\n'
                    "torque_constant_scale = [1.1, 0.9]\nvoltage_constant_scale = [0.95, 1.05]\n"
                    "resistance_scale = [1.2, 0.8]\n")
    arm = load_arm(path)
    assert [float(m.gear_ratio) for m in arm.motors] == [3.0, 5.0] and arm.motors[1].rotor_inertia > 0

    def expect(d, mj):
        joints = mj.describe(d, arm.simulation)["joints"]
        assert [j["armature"] for j in joints] == pytest.approx([9 * 2e-5, 25 * 1e-5], rel=1e-15)
        assert "gear 3" in joints[0]["actuator"] and "gear 5" in joints[1]["actuator"]
    plants_agree(arm, ("mpc", "dobc"), expect)


def test_geared_torque_drives_are_the_same_in_both_plants(tmp_path):
    """A torque drive behind a gear (tau = gr u) with rotor inertia gr^2 Jm: the double pendulum with
    gear ratio 2 and 1e-4 kg m^2 rotors follows derive's plant within the stated tolerance."""
    path = arm_copy(tmp_path, "double_pendulum", {"duration": 5.0})
    path.write_text(path.read_text().replace("gear_ratio = 1.0", "gear_ratio = 2.0").replace(
        "rotor_inertia = 0.0", "rotor_inertia = 1e-4"))
    arm = load_arm(path)

    def expect(d, mj):
        assert [j["armature"] for j in mj.describe(d, arm.simulation)["joints"]] == pytest.approx([4e-4] * 2, rel=1e-15)
    plants_agree(arm, ("npid",), expect)


def test_a_mujoco_without_its_c_library_is_one_error(tmp_path, monkeypatch):
    """The compiled loop links with the wheel's libmujoco and headers; a mujoco package without them
    says so (and that --backend python needs neither)."""
    import types

    from derive.sim.mujoco import compile_flags

    (tmp_path / "mujoco").mkdir()
    monkeypatch.setitem(sys.modules, "mujoco", types.SimpleNamespace(__file__=str(tmp_path / "mujoco" / "__init__.py")))
    with pytest.raises(DeriveError, match="expected MuJoCo's C headers and library in the mujoco package.*--backend python"):
        compile_flags()


def test_the_stepped_plant_refuses_another_step_than_its_model(tmp_path):
    arm = load_arm(arm_copy(tmp_path, "double_pendulum"))
    d = derive(arm)
    stepped = select(arm, "mujoco").stepped(d, arm.simulation)
    stepped.reset(np.zeros(2), 1)
    with pytest.raises(DeriveError, match=r"built for steps of 0.0005 s, asked for 4 steps of 0.001 s"):
        stepped.step(np.zeros((1, 2)), 0.001, 4)
    stepped.step(np.zeros((1, 2)), 0.002, 4)
    assert stepped.theta.shape == stepped.dtheta.shape == (1, 2)


def test_mujocos_warnings_go_into_the_description_not_a_log_file(tmp_path, monkeypatch):
    """MuJoCo's own warnings (here: a deprecated <statistic meaninertia> of the MJCF) are notes of
    the plant's description; nothing is written into the working folder (MuJoCo's default handler
    writes MUJOCO_LOG.TXT there)."""
    monkeypatch.chdir(tmp_path)
    arm = load_arm(_mjcf(tmp_path / "arm"))
    xml = tmp_path / "arm" / "pendulum.xml"
    xml.write_text(xml.read_text().replace("<worldbody>", '<statistic meaninertia="1"/><worldbody>'))
    d = derive(arm)
    notes = select(arm, "mujoco").describe(d, arm.simulation)["notes"]
    assert any(n.startswith("MuJoCo warned:") for n in notes), notes
    assert list(tmp_path.iterdir()) == [tmp_path / "arm"]
