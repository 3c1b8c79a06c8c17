"""A way on for near-physical vendor inertias (issue 19, item 4): refused by default with
the link and the margin; ``repair_inertia`` (arm file) or ``derive init --repair-inertia``
moves each to the Frobenius-nearest physical tensor (derive.model.inertia_repair), reported
link by link; a negative mass is not repairable."""
from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from derive.cli import main
from derive.model.inertia_repair import MARGIN, nearest_physical, project, violation
from derive.model.rigid import inertia_problem
from derive.model.spec import load_arm

from .test_urdf_vendor import CORPUS, chain_of, joint, link, write


def _physical(I) -> bool:
    return inertia_problem(sp.Matrix(3, 3, lambda i, j: sp.Rational(Fraction(I[i][j])))) is None


def _matrix(entries) -> np.ndarray:
    xx, xy, xz, yy, yz, zz = (float(x) for x in entries)
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def test_one_violated_triangle_inequality_has_the_closed_form() -> None:
    """l3 > l1 + l2 by e: l' = l + (e/3)(1, 1, -1), a change of e/sqrt(3) (module docstring)."""
    I = [[Fraction("0.0123"), 0, 0], [0, Fraction("0.0051"), 0], [0, 0, Fraction("0.0070")]]
    assert violation(I) == "principal moments 0.0123 > 0.0051 + 0.007 (violated by 0.0002 kg m^2)"
    fix = nearest_physical(I)
    e = 0.0123 - 0.0051 - 0.0070
    margin = float(MARGIN) * (0.0123 + 0.0051 + 0.0070 + e / 3)   # of the projection's trace
    np.testing.assert_allclose(fix.after, (0.0051 + e / 3 + margin, 0.0070 + e / 3 + margin,
                                           0.0123 - e / 3 + margin), rtol=0, atol=1e-14)
    assert math.isclose(fix.change, e / math.sqrt(3), rel_tol=1e-5)
    assert _physical(_matrix(fix.entries).tolist()) and fix.entries[1] == fix.entries[2] == fix.entries[4] == 0


def test_a_non_psd_tensor_projects_onto_the_cone() -> None:
    """Principal moments (-1, 1, 3) -> (0, 2, 2): the nearest point of {l_i <= l_j + l_k}."""
    np.testing.assert_allclose([float(x) for x in project([-1, 1, 3])], [0, 2, 2], atol=1e-40)
    assert violation([[1, 2, 0], [2, 1, 0], [0, 0, 1]]).startswith("a negative principal moment -1 kg m^2")


@pytest.mark.parametrize("seed", range(6))
def test_the_repair_is_the_frobenius_nearest_physical_tensor(seed: int) -> None:
    """Against an independent solver: min ||X - I||_F over X >= 0 and (tr X / 2) 1 - X >= 0
    (the physical tensors, as an SDP; cvxpy with Clarabel). Our change is the optimum to
    within the stated margin, our tensor is physical, and its principal axes are I's."""
    cp = pytest.importorskip("cvxpy")
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    lam = np.sort(rng.uniform(0.001, 0.01, 3))
    lam[2] = lam[0] + lam[1] + rng.uniform(1e-4, 3e-3)       # break the triangle inequality
    if seed % 2:
        lam[0] = -rng.uniform(1e-5, 1e-3)                     # and positive definiteness
    I = Q @ np.diag(lam) @ Q.T
    I = (I + I.T) / 2
    fix = nearest_physical(I.tolist())
    X = cp.Variable((3, 3), symmetric=True)
    problem = cp.Problem(cp.Minimize(cp.norm(X - I, "fro")), [X >> 0, cp.trace(X) / 2 * np.eye(3) - X >> 0])
    problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-14, tol_gap_rel=1e-12, tol_feas=1e-12)
    trace = float(np.trace(_matrix(fix.entries)))
    assert fix.change <= problem.value + 2 * float(MARGIN) * trace * math.sqrt(3) + 1e-9
    assert problem.value <= fix.change + 1e-9
    assert _physical(_matrix(fix.entries).tolist()) and not _physical(I.tolist())
    R = _matrix(fix.entries)
    assert np.max(np.abs(R @ I - I @ R)) <= 1e-8 * np.max(np.abs(I)) ** 2   # same principal axes


def test_repair_inertia_list_repairs_the_named_link_and_says_so(tmp_path: Path) -> None:
    found, problems = chain_of(CORPUS / "xarm6.urdf", "world", "link6", repair_inertia=["link2", "link3", "link1"])
    assert not problems and found.repaired == ("link2", "link3")
    notes = "\n".join(found.chain.notes)
    assert ("link 'link2': inertia repaired (repair_inertia) to the nearest physical tensor (Frobenius norm, "
            "principal axes kept): principal moments (0.00305792, 0.0236436, 0.0268997) -> ") in notes
    assert "a change of 0.000114 kg m^2 in the Frobenius norm" in notes
    assert "link 'link1': listed in repair_inertia, but its inertia is physical: nothing repaired" in notes
    found, problems = chain_of(CORPUS / "xarm6.urdf", "world", "link6", repair_inertia=["link2"])
    assert found is None and [p.field for p in problems] == ["urdf link 'link3' <inertial><inertia>"]


def test_repair_inertia_naming_an_unknown_link_is_an_error() -> None:
    found, problems = chain_of(CORPUS / "xarm6.urdf", "world", "link6", repair_inertia=["link9"])
    assert found is None and [str(p) for p in problems] == [
        "arm.repair_inertia[1]: expected the name of a link of the URDF, got 'link9', not a link of the URDF"]
    found, problems = chain_of(CORPUS / "xarm6.urdf", "world", "link6", repair_inertia="yes")
    assert found is None and problems[0].field == "arm.repair_inertia"


def test_a_negative_mass_cannot_be_repaired(tmp_path: Path) -> None:
    parts = [link("base"), link("a"), link("b", "-1.0"), joint("j1", "base", "a"), joint("j2", "a", "b")]
    found, problems = chain_of(write(tmp_path, *parts), "base", "b", repair_inertia=True)
    assert found is None and [str(p) for p in problems] == [
        "urdf link 'b' <inertial><mass value>: expected a finite number >= 0 (kg); repair_inertia repairs the "
        "inertia tensor, not a negative mass, got -1.0"]


def test_init_refuses_by_default_and_repairs_with_the_option(tmp_path: Path, capsys) -> None:
    urdf = tmp_path / "xarm6.urdf"
    urdf.write_bytes((CORPUS / "xarm6.urdf").read_bytes())
    assert main(["init", str(urdf)]) == 2
    err = capsys.readouterr().err
    assert "urdf link 'link2' <inertial><inertia>" in err and "derive init --repair-inertia does" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["xarm6.urdf"]
    assert main(["init", str(urdf), "--repair-inertia"]) == 0
    err = capsys.readouterr().err
    assert err.count("derive: note: link 'link") == 2 and "inertia repaired" in err
    text = (tmp_path / "xarm6.toml").read_text()
    assert 'repair_inertia = ["link2", "link3"]' in text and "#   link 'link3': inertia repaired" in text
    arm = load_arm(tmp_path / "xarm6.toml")   # the key it wrote repairs the same links when loaded
    assert arm.n == 6 and sum("inertia repaired" in n for n in arm.chain.notes) == 2
