"""The payload a controller holds (issue 38): J_p and G_p of a payload (eq. 12), the payload limit of the
linearised sampled loop (eq. 15, 21-27, 34 with the true J + J_p, G + G_p), its truth, check's payload-range
obligation, and [payload] / init --payload input checks."""
from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from derive.control import sampling
from derive.control.payload.limits import _rows, centres, payload_limit
from derive.control.pipeline import derive
from derive.dynamics.payload import payload_terms, payload_values
from derive.model.payload import PayloadRange, body_values
from derive.model.spec import arm_from_dict, load_arm
from derive.proofs.payload import check_payload
from derive.proofs.core import Status

DATA = Path(__file__).parent / "data" / "urdf"


def _numeric(exprs: sp.Matrix, sub: dict) -> np.ndarray:
    return np.array(exprs.xreplace(sub).evalf(30).tolist(), dtype=float)


def test_payload_terms_eq12_equal_the_last_body_carrying_it():
    """J + J_p and G + G_p (eq. 12) equal the UR5 whose last body's ten parameters absorb the payload
    (parallel-axis theorem), with the tip link tool0 offset from F_6 (Chain.tip)."""
    d = derive(load_arm(DATA / "ur5.toml"))
    dyn = d.dynamics
    assert dyn.chain.tip is not None                      # tool0 lies 0.0823 m from wrist_3_link's origin
    pt = payload_terms(dyn)
    com, Ic = [0.02, 0.1, 0.05], np.diag([0.01, 0.02, 0.03])
    vals = body_values(dyn.chain, 1.5, com, Ic)          # com in tool0's frame -> F_6
    m, c, I = vals[0], np.array(vals[1:4]), vals[4:]
    Icm = np.array([[I[0], I[1], I[2]], [I[1], I[3], I[4]], [I[2], I[4], I[5]]])
    Io = Icm + m * (c @ c * np.eye(3) - np.outer(c, c))
    added = dict(zip(["m6", "hx6", "hy6", "hz6", "Ixx6", "Ixy6", "Ixz6", "Iyy6", "Iyz6", "Izz6"],
                     [m, *(m * c), Io[0, 0], Io[0, 1], Io[0, 2], Io[1, 1], Io[1, 2], Io[2, 2]]))
    q, dq = [0.3, -0.7, 1.1, 0.4, -0.9, 0.6], [0.5, -1, 0.7, 2, -1.5, 3]
    sub = dict(dyn.subs)
    sub.update(zip(dyn.sym.theta, q))
    sub.update(zip(dyn.sym.dtheta, dq))
    merged = dict(sub)
    for p in dyn.chain.parameters:
        if str(p.symbol) in added:
            merged[p.symbol] = sub[p.symbol] + sp.Float(added[str(p.symbol)], 30)
    sub.update(zip(pt.symbols, vals))
    J = _numeric(dyn.J, sub) + _numeric(pt.J, sub)
    G = _numeric(dyn.G, sub) + _numeric(pt.G, sub)
    assert np.abs(J - _numeric(dyn.J, merged)).max() < 1e-12
    assert np.abs(G - _numeric(dyn.G, merged)).max() < 1e-12
    # the tip transform is applied: tool0's origin is F_6's (0, 0.0823, 0) rotated, so c moved
    assert not np.allclose(c, com)


def test_payload_terms_eq12_planar_point_mass():
    """A planar arm's payload of zero inertia at the tip point mass's place is that point mass made heavier."""
    arm = load_arm("vertical_2link")
    d = derive(arm)
    dyn = d.dynamics
    pt = payload_terms(dyn)
    sub = dict(dyn.subs)
    sub.update(zip(dyn.sym.theta, [0.4, -1.2]))
    sub.update(zip(dyn.sym.dtheta, [2.0, -3.0]))
    heavier = dict(sub)
    pm = next(p.symbol for p in dyn.chain.parameters if p.field == "point_mass[2].mass")
    heavier[pm] = sub[pm] + sp.Rational(3, 10)
    sub.update(zip(pt.symbols, payload_values(0.3, [0.25, 0.0, 0.0], np.zeros((3, 3)))))
    assert np.abs(_numeric(dyn.J, sub) + _numeric(pt.J, sub) - _numeric(dyn.J, heavier)).max() < 1e-13
    assert np.abs(_numeric(dyn.G, sub) + _numeric(pt.G, sub) - _numeric(dyn.G, heavier)).max() < 1e-12


def _radii(d, rng, form, observer, dt, mass):
    rows = _rows(d, rng)
    every = np.arange(len(rows.pts) * len(rows.coms))
    return rows.radii(form, observer, dt, mass, every)


@pytest.mark.parametrize("arm,rng", [
    ("vertical_2link", PayloadRange(mass=0.5, com=(0.05, 0.0, 0.0), com_radius=0.05)),
    ("planar_3link", PayloadRange(mass=0.2, com=(0.0, 0.0, 0.0), com_radius=0.1)),
])
@pytest.mark.parametrize("form", sampling.FORMS)
def test_payload_limit_eq21_27_is_true(arm, rng, form):
    """The stated payload limit is true: the linearised sampled loop is stable at 0.95 x the stated mass at
    every operating point and centre of mass, and unstable at 2 x (the 0.9 margin and the 5 % bisection)."""
    a = load_arm(arm)
    d = derive(replace(a, payload=rng))
    dt = a.simulation.sample_time
    lim = payload_limit(d, form, "explicit", dt, rng)
    assert lim.limit > 0, lim
    assert lim.centres == len(centres(rng)) == 15
    assert _radii(d, rng, form, "explicit", dt, 0.95 * lim.limit).max() < 1.0
    if lim.capped:   # "at least": stable up to the search's cap
        assert lim.worst is None and _radii(d, rng, form, "explicit", dt, lim.raw).max() < 1.0
        return
    assert _radii(d, rng, form, "explicit", dt, 2.0 * lim.limit).max() >= 1.0
    # the worst point and centre of mass are where it fails just above the largest stable mass
    assert lim.worst is not None and len(lim.worst[2]) == 3


def test_payload_limit_zero_payload_is_the_nominal_loop():
    """With no payload the loaded linearisation is the nominal one: the payload search's radii at mass 0
    equal derive.control.sampling's at the same dt."""
    a = load_arm("vertical_2link")
    rng = PayloadRange(mass=0.5)
    d = derive(replace(a, payload=rng))
    dt = a.simulation.sample_time
    loop = sampling._loop(d)
    pts = sampling.operating_points(d)
    L = loop.linearise("dobc", np.array([q for q, _ in pts]), np.array([dq for _, dq in pts]))
    nominal = sampling._radii(loop, "dobc", "explicit", dt, L, exact=True)
    got = _radii(d, rng, "dobc", "explicit", dt, 0.0)
    assert np.all((got < 1.0) == (nominal < 1.0))


def test_check_payload_range_obligation_refutes_beyond_the_limit():
    """check's payload-range obligation: proved within the limit, refuted (the run fails) above it,
    n/a without [payload]; the JSON record is strict."""
    from derive import jsonio
    from derive.control.payload.text import record

    a = load_arm("vertical_2link")
    assert check_payload(derive(a)).status is Status.NOT_APPLICABLE
    probe = PayloadRange(mass=0.5, com=(0.05, 0.0, 0.0), com_radius=0.05)
    held = min(payload_limit(derive(replace(a, payload=probe)), f, "explicit", a.simulation.sample_time, probe).limit
               for f in ("dobc", "npid", "mom"))
    ok = derive(replace(a, payload=replace(probe, mass=0.8 * held)))
    out = check_payload(ok)
    assert out.status is Status.PROVED, out.detail
    bad = derive(replace(a, payload=replace(probe, mass=1.5 * held)))
    out = check_payload(bad)
    assert out.status is Status.REFUTED and "NOT hold" in out.detail and "first fails at theta" in out.detail
    rec = json.loads(jsonio.dumps(record(bad)))
    assert rec["holds"] is False and set(rec["forms"]) == set(sampling.FORMS)


def _run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "derive", *args], capture_output=True, text=True, cwd=cwd)


def test_init_payload_designs_for_the_range(tmp_path):
    """init --payload MASS writes [payload] and shapes W, K and the sample time until DOBC, NPID and MOM hold
    the range at the worst centre of mass; the nominal starter of the same arm does not hold it."""
    (tmp_path / "dp.urdf").write_text((DATA / "double_pendulum.urdf").read_text())
    plain = _run("init", "dp.urdf", "--out", "plain.toml", cwd=tmp_path)
    assert plain.returncode == 0, plain.stderr
    mass = 4.0
    proc = _run("init", "dp.urdf", "--out", "dp.toml", "--payload", str(mass), "--payload-radius", "0.1", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    arm = load_arm(tmp_path / "dp.toml")
    assert arm.payload == PayloadRange(mass=mass, com=(0.0, 0.0, 0.0), com_radius=0.1)
    out = check_payload(derive(arm))
    assert out.status is Status.PROVED, out.detail
    nominal = replace(load_arm(tmp_path / "plain.toml"), payload=arm.payload)
    assert check_payload(derive(nominal)).status is Status.REFUTED
    text = (tmp_path / "dp.toml").read_text()
    assert "holds the whole [payload] range" in text and "momentum_gain = [" in text
    # W = omega Jbar + rho Jp_bar: the nominal W plus a positive semidefinite term (the certificate's
    # 2 W - J' only grows), rho stated in the file
    W, W0 = (np.array([[float(x) for x in row] for row in a.controller.W]) for a in (arm, nominal))
    assert np.linalg.eigvalsh((W - W0 + (W - W0).T) / 2).min() > -1e-3 * np.abs(W).max()
    assert np.abs(W - W0).max() > 0 and "W = omega Jbar + rho Jp_bar (rho = " in text


def test_design_ladder_round_sample_times():
    """The sample times the payload design tries: round values, longest first, none above the start or below
    the floor."""
    from derive.control.payload.design import MIN_SAMPLE_TIME, ladder

    assert ladder(2e-3) == [2e-3, 1e-3, 5e-4, 4e-4, 2.5e-4, 2e-4, 1e-4, 5e-5, 4e-5, 2.5e-5, 2e-5]
    assert ladder(3e-4) == [2.5e-4, 2e-4, 1e-4, 5e-5, 4e-5, 2.5e-5, 2e-5]
    assert ladder(1e-5) == [] and min(ladder(1.0)) == MIN_SAMPLE_TIME


def test_design_rate_is_the_largest_the_sample_time_allows():
    """rho of a sample time dt: W = W0 + rho Jp_bar has its fastest observer rate (the eigenvalues of W J^-1
    over the statement's points) within RATE_DT / dt, and 2 % more rho exceeds it; K_i within it too."""
    from derive.control.payload.design import RATE_DT, _Shape

    arm = load_arm(DATA / "double_pendulum.toml")
    d = derive(arm)
    rng = PayloadRange(mass=4.0, com=(0.0, 0.0, 0.0), com_radius=0.1)
    W0 = np.array([[float(x) for x in row] for row in arm.controller.W])
    shape = _Shape(d, rng, W0, (50.0, 50.0))
    for dt in (1e-3, 1e-4):
        rho = shape.rate_for(dt)
        assert rho > 0
        W, K = shape.gains(rho, dt)
        assert shape.rates(W)[1] <= RATE_DT / dt * (1 + 1e-9) < shape.rates(shape.gains(1.02 * rho, dt)[0])[1]
        assert max(K) <= RATE_DT / dt * (1 + 1e-3) and min(K) >= 50.0
    assert shape.rate_for(1e-3) < shape.rate_for(1e-4)


@pytest.mark.parametrize("table,field", [
    ({"mass": -1.0}, "payload.mass"),
    ({"mass": float("nan")}, "payload.mass"),
    ({"mass": float("inf")}, "payload.mass"),
    ({"mass": 1.0, "com": [0.0, 0.0, 2.5]}, "payload.com"),
    ({"mass": 1.0, "com": [0.0, 0.0, 1.5], "com_radius": 0.6}, "payload.com_radius"),
    ({"mass": 1.0, "com_radius": -0.1}, "payload.com_radius"),
    ({"mass": 1.0, "com": [0.0, 0.0]}, "payload.com"),
    ({"mass": 1.0, "inertia": [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 3.0]]}, "payload.inertia"),
    ({"mass": 1.0, "inertia": [[1.0, 0.5, 0], [0, 1.0, 0], [0, 0, 1.0]]}, "payload.inertia"),
    ({"mass": 1.0, "inertia": [[-1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]}, "payload.inertia"),
    ({"mass": 1.0, "size": 2}, "payload.size"),
])
def test_bad_payload_table_one_clear_problem(table, field):
    """A bad [payload] table: one problem naming the field, what was expected and what was given."""
    from derive.errors import SpecError
    from derive.model.examples import planar_chain_dict

    data = planar_chain_dict(2)
    data["payload"] = table
    with pytest.raises(SpecError) as err:
        arm_from_dict(data)
    problems = err.value.problems
    assert [p.field for p in problems] == [field], problems
    assert problems[0].expected and problems[0].given


@pytest.mark.parametrize("args,message", [
    (["--payload", "-1"], "--payload: expected"),
    (["--payload", "nan"], "--payload: expected a finite number"),
    (["--payload", "1", "--payload-com", "0,0,3"], "--payload-com: expected"),
    (["--payload", "1", "--payload-radius", "-2"], "--payload-radius: expected"),
])
def test_init_bad_payload_exit_2_nothing_written(tmp_path, args, message):
    """init --payload with an impossible value: exit 2, one message, no file."""
    (tmp_path / "dp.urdf").write_text((DATA / "double_pendulum.urdf").read_text())
    proc = _run("init", "dp.urdf", "--out", "dp.toml", *args, cwd=tmp_path)
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dp.urdf"]
