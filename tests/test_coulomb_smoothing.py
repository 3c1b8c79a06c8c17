"""Issue 34 item 1: the smooth Coulomb law tau_c tanh(theta'/eps) with a per-joint width eps
(``[simulation] coulomb_smoothing``): its validation, every plant applying it (the Python plant and
the compiled loop: tests/test_compiled_loop.py; MuJoCo's: tests/test_mujoco_plant.py; the plant FMU
here), and ``derive init`` widening a light joint's eps so that its starter needs at most 8 RK4
substeps (the xArm6's 92 took 134 s CPU to simulate)."""
from __future__ import annotations

import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.errors import SpecError
from derive.model.simspec import COULOMB_SMOOTHING, parse_simulation
from derive.model.spec import resolve_arm_path
from derive.sim.plant import Plant, stiffest_mode, true_plant

URDF = Path(__file__).parent / "data" / "urdf"

BAD = [
    ("coulomb_smoothing = 0.0", "0.0"),
    ("coulomb_smoothing = -0.1", "-0.1"),
    ("coulomb_smoothing = [0.01, nan]", "[0.01, nan]"),
    ("coulomb_smoothing = [0.01]", "[0.01]"),
    ("coulomb_smoothing = [0.01, 0.0]", "[0.01, 0.0]"),
    ('coulomb_smoothing = "wide"', "'wide'"),
]


@pytest.mark.parametrize("line,given", BAD, ids=["zero", "negative", "nan", "one of two", "a zero", "text"])
def test_issue34_a_bad_coulomb_smoothing_is_one_clear_error_naming_field_expected_and_given(tmp_path, line, given):
    path = tmp_path / "arm.toml"
    path.write_text(resolve_arm_path(None).read_text() + f"\n[simulation]\n{line}\n")
    with pytest.raises(SpecError, match=re.escape(
            "simulation.coulomb_smoothing: expected a finite number > 0 [rad/s; m/s prismatic] for every joint, "
            "or an array of 2 of them: the width eps of tau_c tanh(theta'/eps), got " + given)) as info:
        derive.load_arm(path)
    assert str(info.value).count("coulomb_smoothing") == 1


def test_issue34_coulomb_smoothing_is_one_number_for_all_or_one_per_joint_and_defaults_to_0_01():
    assert parse_simulation({}, 3)[0].coulomb_smoothing == (COULOMB_SMOOTHING,) * 3 == (0.01,) * 3
    one, problems = parse_simulation({"coulomb_smoothing": 0.1}, 3)
    assert one == replace(parse_simulation({}, 3)[0], coulomb_smoothing=(0.1, 0.1, 0.1)) and problems == []
    assert parse_simulation({"coulomb_smoothing": [0.01, 0.2, 1]}, 3)[0].coulomb_smoothing == (0.01, 0.2, 1.0)


def test_issue34_the_width_sets_the_stiffest_mode_and_the_python_plant_applies_it():
    """The smooth law's slope at rest is tau_c / eps: a wider eps, a slower stiffest mode; the Python
    plant's friction torque at theta' = eps is tau_c tanh(1) (J times the change of theta'' it makes)."""
    arm = derive.load_arm()
    s = replace(arm.simulation, coulomb_friction=(0.5, 0.3))
    d = derive.derive(replace(arm, simulation=s))
    assert stiffest_mode(d, replace(s, coulomb_smoothing=(0.1, 0.1)))["rate"] < stiffest_mode(d, s)["rate"]
    wide = replace(s, coulomb_smoothing=(0.2, 0.05))
    plant, bare = Plant(d, true_plant(d, wide)), Plant(d, true_plant(d, replace(wide, coulomb_friction=(0.0, 0.0))))
    q, dq, u = np.array([[0.3, -0.2]]), np.array([[0.2, 0.05]]), np.zeros((1, 2))
    J, _ = plant.matrices(q, dq)
    np.testing.assert_allclose(J[0] @ (bare.accel(q, dq, u) - plant.accel(q, dq, u))[0],
                               np.array([0.5, 0.3]) * np.tanh(1.0), rtol=1e-9, atol=0,
                               err_msg="friction torque at theta' = eps")


def test_issue34_plant_fmu_exposes_the_widths_with_min_0_rejects_0_and_applies_them(tmp_path):
    """``coulomb_smoothing[i]``: a tunable parameter beside ``coulomb[i]``, min 0 (exclusive: the setter
    refuses 0), and a set width is the one the FMU integrates (derive's Python plant with it, 1e-12)."""
    from .fmuplant import built, fmu_run, plant_run

    arm = derive.load_arm()
    s = replace(arm.simulation, coulomb_friction=(0.5, 0.3), coulomb_smoothing=(0.2, 0.05))
    d = derive.derive(replace(arm, simulation=s))
    files = built(d, tmp_path)
    variables = files[1]
    for i, width in ((1, 0.2), (2, 0.05)):
        v = variables[f"coulomb_smoothing[{i}]"]
        assert (v.causality, v.variability, float(v.start), float(v.min), v.unit) == (
            "parameter", "tunable", width, 0.0, "rad/s"), v
        assert "tanh(theta'/eps)" in v.description and f"coulomb[{i}]" in variables
    steps, u = 300, np.array([1.0, -0.5])

    def runs(widths) -> tuple[np.ndarray, np.ndarray]:
        start = {"coulomb_smoothing[1]": widths[0], "coulomb_smoothing[2]": widths[1]}
        return (fmu_run(files, s, steps, u, start, refused={"coulomb_smoothing[1]": 0.0}),
                plant_run(d, replace(s, coulomb_smoothing=tuple(widths)), steps, u))

    for widths in ((0.2, 0.05), (0.01, 0.5)):
        fmu, plant = runs(widths)
        np.testing.assert_allclose(fmu, plant, rtol=0, atol=1e-12, err_msg=str(widths))
    assert np.max(np.abs(runs((0.2, 0.05))[1] - runs((0.01, 0.5))[1])) > 1e-6


def _init(tmp_path: Path, name: str, *options: str) -> Path:
    urdf = tmp_path / Path(name).name
    shutil.copy(URDF / name, urdf)
    assert main(["init", str(urdf), *options]) == 0
    return urdf.with_suffix(".toml")


def test_issue34_init_widens_the_xarm6_wrists_coulomb_law_to_at_most_8_substeps_and_simulate_runs(tmp_path,
                                                                                                    capsys):
    """The xArm6's <dynamics friction="1"> on every joint: at eps = 0.01 its light wrist needs 92 RK4
    substeps at 0.2 ms; init widens the joints that make it so to round widths, writes why and how to
    have the sharp law back, and the file loads, is stable as written and simulates."""
    from derive.cli.init_numbers import MAX_SUBSTEPS

    path = _init(tmp_path, "corpus/xarm6.urdf", "--base", "world", "--tip", "link6", "--repair-inertia")
    text = path.read_text()
    arm = derive.load_arm(path)
    s = arm.simulation
    assert s.coulomb_friction == (1.0,) * 6 and s.sample_time == 0.0002
    assert s.substeps <= MAX_SUBSTEPS and any(w > 0.01 for w in s.coulomb_smoothing)
    assert all(f"{w:.0e}"[0] in "125" and float(f"{w:.0e}") == w for w in s.coulomb_smoothing)   # the 1-2-5 series
    sharp = int(re.search(r"coulomb_smoothing = 0\.01 and substeps = (\d+)\.", text).group(1))
    assert sharp > MAX_SUBSTEPS
    for i, w in enumerate(s.coulomb_smoothing):
        if w != 0.01:
            assert f"'joint{i + 1}' 0.01 -> {w:g} rad/s" in text
    assert "Simscape's Rotational Friction block" in text
    d = derive.derive(arm)
    assert stiffest_mode(d, s)["stable"]
    assert stiffest_mode(d, replace(s, coulomb_smoothing=(0.01,) * 6))["substeps"] == sharp
    narrower = [replace(s, coulomb_smoothing=tuple(0.01 if j == i else w for j, w in enumerate(s.coulomb_smoothing)))
                for i, w in enumerate(s.coulomb_smoothing) if w != 0.01]
    assert all(stiffest_mode(d, n)["substeps"] > MAX_SUBSTEPS for n in narrower)   # each widening is needed
    capsys.readouterr()
    assert main(["simulate", str(path), "--controllers", "npid", "--duration", "0.3", "--out",
                 str(tmp_path / "sim")]) == 0
    assert "stiffest mode" not in capsys.readouterr().err


def test_issue34_init_writes_no_widening_for_the_ur5(tmp_path):
    path = _init(tmp_path, "ur5.urdf", "--base", "base_link", "--tip", "tool0")
    text = path.read_text()
    assert "coulomb_smoothing" not in text and not re.search(r"^substeps", text, flags=re.M)
    assert derive.load_arm(path).simulation.coulomb_smoothing == (0.01,) * 6


def test_issue34_a_sweeps_worst_file_states_the_widths_and_reads_back_the_same():
    from derive.cli.sweep import simulation_table
    from derive.model.simspec import SimSettings, default_settings

    s = replace(default_settings(3), coulomb_smoothing=(0.01, 0.2, 0.5))
    assert simulation_table(s)["coulomb_smoothing"] == [0.01, 0.2, 0.5]
    assert parse_simulation(simulation_table(s), 3) == (s, [])
    assert "coulomb_smoothing" not in simulation_table(SimSettings())   # () is eps = 0.01 each: left unsaid
