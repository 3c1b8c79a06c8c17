"""The starter experiment's pulses per joint, in the joint's own unit (issue 34 item 5, the Fetch's kind).

``derive init`` on the Fetch started its prismatic torso (0 to 0.386 m) at its lower limit, and one
``amplitude_deg`` set by the torso's travel (0.8 x 0.386 m read as 0.309 rad = 17.7 deg) shrank
every revolute joint's pulse. ``round4/lift.urdf`` is that kind (a 0 to 0.386 m lift under two
revolute joints, written for derive): main wrote ``initial_theta = [0, 0, 0]`` and
``amplitude_deg = 17.7`` for it. Now ``[simulation] amplitude`` holds one amplitude per joint (rad;
m prismatic), ``amplitude_deg`` still works, and every plant (derive's compiled loop, MuJoCo's,
the plant FMU) reads the same pulses."""
from __future__ import annotations

import math
import shutil
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Slave

import derive
from derive.cli import main
from derive.cli.init_numbers import POSE_MARGIN, PULSE_CAP, PULSE_ROOM
from derive.errors import SpecError
from derive.model.simspec import default_settings, parse_simulation, pulse_amplitudes
from derive.sim.simulate import pulses

LIFT = Path(__file__).parent / "data" / "urdf" / "round4" / "lift.urdf"


@pytest.fixture(scope="module")
def lift(tmp_path_factory):
    """``derive init`` of the lift: the file and its arm."""
    folder = tmp_path_factory.mktemp("lift")
    shutil.copy(LIFT, folder / "lift.urdf")
    assert main(["init", str(folder / "lift.urdf")]) == 0
    return folder / "lift.toml", derive.load_arm(folder / "lift.toml")


def test_init_starts_inside_every_range_and_gives_each_joint_its_own_pulse(lift):
    path, arm = lift
    text = path.read_text()
    assert "amplitude_deg" not in text and "\namplitude = [" in text
    s = arm.simulation
    lo = np.array([float(j.limits.lower) for j in arm.chain.joints])
    hi = np.array([float(j.limits.upper) for j in arm.chain.joints])
    q0, amp = np.array(s.initial_theta), np.array(s.amplitude)
    travel = hi - lo
    assert np.all(q0 >= lo + POSE_MARGIN * travel - 1e-4) and np.all(q0 <= hi - POSE_MARGIN * travel + 1e-4)
    assert q0[0] >= 0.019                        # the torso: no longer at its lower limit 0
    assert amp[0] == pytest.approx(travel[0] / 2, rel=2e-3)   # metres: half the lift's travel, 0.193 m
    assert np.all(amp[1:] == pytest.approx(PULSE_CAP, rel=2e-3))   # the revolute joints keep the paper's 90 deg
    assert np.all(q0 + amp <= q0 + PULSE_ROOM * (hi - q0) + 1e-9)   # every pulse 20 % of its room short of the top
    assert s.reference_start == "measured"


def test_the_pulses_every_plant_reads_are_the_files_per_joint_amplitudes(lift, tmp_path, capsys):
    """derive simulate (the compiled loop): y_d settles at y_d(0) + amplitude on each joint in its unit,
    no joint leaves its range; the plant FMU's amplitude[i] parameters (m, rad) are the file's and its
    y_d equals the compiled loop's."""
    from derive.fmu import plant_fmu
    from derive.sim.compiled import build
    from derive.sim.simulate import run_compiled, true_plant

    path, arm = lift
    assert main(["simulate", str(path), "--duration", "20", "--out", str(tmp_path / "sim")]) == 0
    assert "leaves its range" not in capsys.readouterr().err
    d = derive.derive(arm)
    s = replace(arm.simulation, duration=14.0)
    trace = run_compiled(d, build(d, "explicit"), true_plant(d, s), s, "dobc")
    q0, amp = np.array(s.initial_theta), np.array(s.amplitude)
    k = int(round(4.9 / s.sample_time))         # joint 1 pulsed from t = 0, joints 2, 3 from 5 and 10 s
    assert trace.yd[k, 0] - q0[0] == pytest.approx(amp[0], rel=0.02)     # the lift's 0.193 m pulse, settled
    assert trace.yd[-1, 1] - q0[1] == pytest.approx(amp[1], rel=0.02)
    name, data = plant_fmu(d, 3)
    fmu = tmp_path / name
    fmu.write_bytes(data)
    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    assert [float(var[f"amplitude[{i}]"].start) for i in (1, 2, 3)] == list(s.amplitude)
    assert [var[f"amplitude[{i}]"].unit for i in (1, 2, 3)] == ["m", "rad", "rad"]
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path / "x")
    f = FMU3Slave(guid=md.guid, unzipDirectory=str(tmp_path / "x"), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="lift")
    f.instantiate()
    f.enterInitializationMode(startTime=0.0)
    f.exitInitializationMode()
    yd = [var[f"yd[{i}]"].valueReference for i in (1, 2, 3)]
    steps = int(round(2.0 / s.sample_time))
    got = []
    for j in range(steps):
        f.doStep(currentCommunicationPoint=j * s.sample_time, communicationStepSize=s.sample_time)
        got.append(f.getFloat64(yd))
    f.terminate()
    f.freeInstance()
    np.testing.assert_allclose(np.array(got), trace.yd[1:steps + 1], rtol=0, atol=1e-12)


def test_amplitude_per_joint_or_amplitude_deg_for_all_but_not_both():
    s, problems = parse_simulation({"amplitude": [0.1, 0.5]}, 2)
    assert not problems and pulse_amplitudes(s, 2) == (0.1, 0.5)
    s, problems = parse_simulation({"amplitude_deg": 30.0}, 2)
    assert not problems and pulse_amplitudes(s, 2) == (math.radians(30),) * 2
    assert pulse_amplitudes(default_settings(3), 3) == (math.radians(90),) * 3
    _, problems = parse_simulation({"amplitude": [0.1, 0.5], "amplitude_deg": 30.0}, 2)
    assert [(p.field, p.expected) for p in problems] == [
        ("simulation.amplitude", "either amplitude (per joint, rad or m) or amplitude_deg (every joint, deg), not both")]
    _, problems = parse_simulation({"amplitude": [0.1]}, 2)
    assert problems[0].field == "simulation.amplitude" and "an array of 2 finite numbers" in problems[0].expected
    r = pulses(replace(default_settings(2), amplitude=(0.1, 0.5), start=(0.0, 0.0)), 2, 3)
    assert r.tolist() == [[0.1, 0.5]] * 3


def test_an_arm_file_with_both_keys_is_one_clear_error(tmp_path, capsys):
    arm = tmp_path / "a.toml"
    text = (Path(derive.__file__).parent / "model" / "arms" / "glasgow_2link.toml").read_text()
    arm.write_text(text + "\n[simulation]\namplitude = [0.1, 0.2]\namplitude_deg = 10.0\n")
    with pytest.raises(SpecError, match=r"simulation\.amplitude: expected either amplitude"):
        derive.load_arm(arm)
    assert main(["simulate", str(arm), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "simulation.amplitude" in err and "Traceback" not in err


def test_a_sweeps_worst_sample_file_writes_one_of_the_two_keys_and_reads_back_the_same_settings():
    """derive sweep writes every [simulation] key of a worst sample (derive.cli.sweep.simulation_table):
    per-joint amplitudes, or amplitude_deg, never both (the file would be refused)."""
    from derive.cli.sweep import simulation_table

    for s in (replace(default_settings(2), amplitude=(0.1, 0.5)), replace(default_settings(2), amplitude_deg=30.0)):
        table = simulation_table(s)
        assert ("amplitude" in table) != ("amplitude_deg" in table)
        back, problems = parse_simulation(table, 2)
        assert not problems and back == s
