"""Units follow the actuation (issue 20 items 3 and 7): in torque mode u, the disturbance d,
dhat and the input limits are in N m in every output (header, Python module, FMU description,
show, simulate's metrics and plots); W is in N m s/rad in both modes (p = W theta' is a joint
torque: z + p = B dhat, eq. 22), its rates W J^-1 in 1/s."""
from __future__ import annotations

from pathlib import Path

import pytest

import derive
from derive.codegen.files import generate_files
from derive.codegen.forms import FORMS
from derive.codegen.kernels import ParamsMode
from derive.codegen.views import arm_view

DATA = Path(__file__).parent / "data" / "urdf"


@pytest.fixture(scope="module")
def torque():
    return derive.derive(derive.load_arm(DATA / "continuous.toml"))   # two joints, torque actuation


@pytest.fixture(scope="module")
def voltage():
    return derive.derive(derive.load_arm())


def test_generated_files_of_a_torque_arm_say_n_m_and_never_volts(torque):
    files = generate_files(torque, None, "double", ParamsMode.RUNTIME)
    for path, text in files.items():
        assert "[V]" not in text and "volt" not in text.lower(), path
    header, module = files["c/contarm.h"], files["python/contarm.py"]
    assert "Torque limits [N m] (0 = none)" in header and "u_max[2];  /* torque limits [N m], 0 = none */" in header
    assert "torque limits [N m], 0 = none" in module
    assert "observer gain w1 (eq. 25) [N m s/rad], from controller.w[1]" in header
    assert "Observer gain W = [[5, 0], [5, 5]] N m s/rad" in header and "W J^-1 are in 1/s" in header


def test_a_voltage_arm_keeps_volts_and_w_is_n_m_s_per_rad(voltage):
    v = arm_view(voltage, "double", ParamsMode.RUNTIME)
    assert (v.u_word, v.u_unit) == ("voltage", "V")
    header = generate_files(voltage, None, "double", ParamsMode.RUNTIME)["c/glasgow_2link.h"]
    assert "Voltage limits [V] (0 = none)" in header and "[N m s/rad], from controller.w[1]" in header
    assert "1/s" not in header.split("Observer gain")[1].split("eq. 23-25")[0]


def test_fmu_descriptions_of_a_torque_arm_say_n_m(torque):
    from derive.fmu.describe import plant_view, variables

    v = arm_view(torque, "double", ParamsMode.RUNTIME)
    found, units, _ = variables(torque, v, FORMS["dobc"], 3)
    by = {x.name: x for x in found}
    for name in ("u[1]", "dhat[2]", "u_max[1]"):
        assert by[name].unit == "N.m", name
    assert by["u[1]"].description.startswith("torque of motor 1") and by["w1"].unit == "N.m.s/rad"
    assert "volt" not in " ".join(x.description for x in found).lower()
    p = plant_view(torque, 3, token="", tool="t", sample_time=1e-3, sources=())
    plant = {x.name: x for x in p.variables}
    assert plant["u[1]"].unit == plant["dist[1]"].unit == plant["u_max[2]"].unit == "N.m"
    assert "volt" not in (p.description + " ".join(x.description for x in p.variables)).lower()


def test_show_and_simulate_of_a_torque_arm_say_n_m(torque, capsys):
    from derive.cli.show import render_text
    from derive.cli.simulate import metrics_markdown, metrics_results

    text = render_text(torque, unicode=False)
    assert "u torques [N m]" in text and "observer gain [N m s/rad]" in text and "volt" not in text.lower()
    md = metrics_markdown("contarm", {}, "compiled", "N m", "torque")
    assert "control effort is the RMS torque [N m]" in md
    assert metrics_results([], None, "N m")["_units"]["control_effort"] == "N m"
