"""Operating-point grids within the joint limits, and J singular there (issue 19 item 5;
derive.control.sampling.grid): the case singular_pose_crash (tests/data/urdf/round3/): J = diag(0.09 cos^2
theta2, 0.09), singular at theta2 = +-pi/2. With j2 in [-3, 3] rad every command refuses it naming
the pose (exit 2, nothing written); with j2 in [-1, 1] rad the singular poses lie outside the
limits and nothing is refused."""
from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.control.sampling.grid import check_definite
from derive.errors import SpecError

CASES = Path(__file__).parent / "data" / "urdf" / "round3"


def test_a_singular_pose_within_the_limits_is_one_error_naming_it():
    arm = derive.load_arm(CASES / "singular_at_pose.toml")
    with pytest.raises(SpecError, match=r"J\(theta\) singular within the joint limits of .*singular_at_pose.toml "
                                        r"\(1 problem\):\n  - urdf joint 'j2' \(the inertia matrix J\(theta\) within "
                                        r"the joint limits\): expected J positive definite .*got J singular at "
                                        r"theta2 = -?pi/2 \(-?1.5708 rad\)"):
        derive.derive(arm)


@pytest.mark.parametrize("command", [["show"], ["check"], ["generate", "--out", "out"], ["simulate", "--out", "out"],
                                     ["tune", "--speed", "1,1"]])
def test_every_command_refuses_it_with_exit_2_and_writes_nothing(tmp_path, monkeypatch, capsys, command):
    monkeypatch.chdir(tmp_path)
    assert main([command[0], str(CASES / "singular_at_pose.toml"), *command[1:]]) == 2
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and "theta2 = " in captured.err and "pi/2" in captured.err
    assert captured.out == "" and list(tmp_path.iterdir()) == []


def test_singular_poses_outside_the_limits_are_no_error(capsys):
    d = derive.derive(derive.load_arm(CASES / "lim.toml"))      # j2 in [-1, 1]: J22 >= 0.09 cos^2(1) > 0
    check_definite(d)
    assert main(["show", str(CASES / "lim.toml")]) == 0
    assert "Sample time:" in capsys.readouterr().out


def test_a_grid_point_where_j_is_singular_is_caught_too():
    """The grid's own configurations are checked (the search is seeded; a grid point on the singularity is exact)."""
    d = derive.derive(derive.load_arm(CASES / "lim.toml"))
    with pytest.raises(SpecError, match=r"theta2 = pi/2 \(1.5708 rad\)"):
        check_definite(d, np.array([[0.0, np.pi / 2]]))


def test_the_singular_j_search_stops_creeping_and_finds_the_same_least_ratio():
    """The iiwa's J is ill-conditioned (lambda_min / lambda_max 2.3e-4) but nowhere singular: the compass search
    crept toward it by relative steps below 1e-6 for all of its 400 rounds. Moving only on improvements above
    CREEP, it ends within 60 rounds at the same least ratio (to 1e-5 relative)."""
    g = importlib.import_module("derive.control.sampling.grid")   # the package's name `grid` is the function
    d = derive.derive(derive.load_arm(Path(__file__).parent / "data" / "urdf" / "iiwa.toml"))
    mass = g.mass_function(d)
    s = g.spans(d)
    lo, hi = np.array([a for a, _, _ in s]), np.array([b for _, b, _ in s])
    Q = lo + (hi - lo) * np.random.default_rng(1).random((g.SEARCH, d.n))
    r = g._ratio(mass(Q))
    starts = np.argsort(r)[:3]
    rounds = [0]

    def values(T):
        rounds[0] += 1
        return g._ratio(mass(T.reshape(-1, d.n))).reshape(T.shape[:2])

    _, creep = g.compass(values, Q[starts], r[starts], lo, hi, 0.125, 1e-8, 400, maximise=False, rtol=g.CREEP)
    used, rounds[0] = rounds[0], 0
    _, plain = g.compass(values, Q[starts], r[starts], lo, hi, 0.125, 1e-8, 400, maximise=False)
    assert used < 60 < rounds[0]
    assert creep.min() == pytest.approx(plain.min(), rel=1e-5) and creep.min() > g.SINGULAR
