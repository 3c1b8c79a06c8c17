"""The generated Python module checks what it is given (issue 10, item 10).

For the default arm, ``mpc_step(Input(theta=np.array([0.1, 0.2, 0.3]), ...))`` returned
OK with a u computed from the first two angles; ``theta=[0.1]`` raised a bare IndexError
and a nested list a TypeError about scalars. Every public function of a generated module
now checks every argument with one generic checker: a vector that is not N real numbers
(shape (N,)) raises ValueError (wrong shape) or TypeError (not real numbers) naming the
argument, the expected shape and what it got; dt must be a real number; state and inp must
be the module's objects; in runtime mode each parameter too. Non-finite values keep their
documented error codes.
"""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

import derive
from derive import jsonio
from derive.codegen.emit import write_tree
from derive.codegen.files import python_files
from derive.codegen.kernels import ParamsMode


def _load(tmp_path_factory, mode: str):
    d = derive.derive(derive.load_arm())
    root = tmp_path_factory.mktemp(f"py_{mode}") / "glasgow_2link"
    files = python_files(d, ParamsMode(mode))
    write_tree(root, {**files, "MANIFEST.json": jsonio.dumps({"files": sorted(files)})})
    spec = importlib.util.spec_from_file_location(f"glasgow_2link_{mode}", root / "python" / "glasgow_2link.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


@pytest.fixture(scope="module", params=["baked", "runtime"])
def module(request, tmp_path_factory):
    return _load(tmp_path_factory, request.param)


@pytest.fixture(scope="module")
def runtime(tmp_path_factory):
    return _load(tmp_path_factory, "runtime")


def _args(m):
    return (m.Params(),) if hasattr(m, "Params") else ()


def _input(m, **fields):
    x = {"theta": [0.1, 0.2], "dtheta": [0.0, 0.1], "yd": [0.5, 0.5], "dyd": [0.0, 0.0], "ddyd": [0.0, 0.0]}
    return m.Input(**{**x, **fields})


def test_the_instance_three_angles_for_two_joints_is_a_value_error(module):
    m = module
    inp = _input(m, theta=np.array([0.1, 0.2, 0.3]))
    with pytest.raises(ValueError, match=r"^inp\.theta: expected shape \(2,\), got shape \(3,\)$"):
        m.mpc_step(*_args(m), inp)


# (bad value, exception, what the message says it got)
BAD_VECTORS = [
    ([0.1], ValueError, r"got shape \(1,\)"),
    ([[0.1], [0.2]], ValueError, r"got shape \(2, 1\)"),
    (np.array([[0.1, 0.2]]), ValueError, r"got shape \(1, 2\)"),
    ([[0.1, 0.2], [0.3]], ValueError, r"got a ragged nested sequence"),
    (0.1, TypeError, r"got float 0\.1"),
    (None, TypeError, r"got NoneType None"),
    ("ab", TypeError, r"got str 'ab'"),
    ([0.1, "x"], TypeError, r"got str 'x'"),
    ([True, 0.1], TypeError, r"got bool True"),
    ([1j, 0.1], TypeError, r"got complex 1j"),
    (np.array(["a", "b"]), TypeError, r"got an array of <U1"),
]


def _calls(m, **inp_fields):
    """Every public function with an Input that has ``inp_fields``."""
    p = _args(m)
    inp = _input(m, **inp_fields)
    return {"mpc_step": lambda: m.mpc_step(*p, inp), "npid_init": lambda: m.npid_init(*p, m.NpidState(), inp),
            "npid_step": lambda: m.npid_step(*p, m.NpidState(), inp, 1e-3),
            "dobc_init": lambda: m.dobc_init(*p, m.DobcState(), inp),
            "dobc_step": lambda: m.dobc_step(*p, m.DobcState(), inp, 1e-3),
            "dobc_estimate": lambda: m.dobc_estimate(*p, m.DobcState(), inp),
            "mom_init": lambda: m.mom_init(*p, m.MomState(), inp),   # the momentum observer (issue 12 item 6)
            "mom_step": lambda: m.mom_step(*p, m.MomState(), inp, 1e-3),
            "mom_estimate": lambda: m.mom_estimate(*p, m.MomState(), inp)}


@pytest.mark.parametrize("bad,error,got", BAD_VECTORS, ids=[repr(b)[:24] for b, _, _ in BAD_VECTORS])
def test_every_function_names_every_bad_vector(module, bad, error, got):
    m = module
    for field in ("theta", "dtheta", "yd", "dyd", "ddyd"):
        for name, call in _calls(m, **{field: bad}).items():
            with pytest.raises(error, match=rf"^inp\.{field}: expected (shape \(2,\)|2 real numbers, shape \(2,\)), "
                                            rf"{got}$"):
                call()
    with pytest.raises(error, match=rf"^theta: expected .*shape \(2,\).*{got}$"):
        m.gains(*_args(m), bad)
    p = _args(m)
    for name, state, field, call in (
            ("npid_step", m.NpidState(), "int_e", lambda s: m.npid_step(*p, s, _input(m), 1e-3)),
            ("dobc_step", m.DobcState(), "z", lambda s: m.dobc_step(*p, s, _input(m), 1e-3)),
            ("dobc_estimate", m.DobcState(), "z", lambda s: m.dobc_estimate(*p, s, _input(m))),
            ("mom_step", m.MomState(), "m", lambda s: m.mom_step(*p, s, _input(m), 1e-3)),
            ("mom_estimate", m.MomState(), "m", lambda s: m.mom_estimate(*p, s, _input(m)))):
        setattr(state, field, bad)
        with pytest.raises(error, match=rf"^state\.{field}: expected .*shape \(2,\).*{got}$"):
            call(state)
    ok = [0.1, 0.2]
    for name, args in (("mass_matrix", ("theta",)), ("bias", ("theta", "dtheta")), ("gravity", ("theta",)),
                       ("forward_dynamics", ("theta", "dtheta", "u", "d"))):  # the plant model
        for k, arg in enumerate(args):
            values = [bad if j == k else ok for j in range(len(args))]
            with pytest.raises(error, match=rf"^{arg}: expected .*shape \(2,\).*{got}$"):
                getattr(m, name)(*p, *values)


def test_dt_state_and_input_of_the_wrong_kind_are_type_errors(module):
    m = module
    p = _args(m)
    for dt, shown in (([1e-3], r"list \[0\.001\]"), ("0.001", r"str '0\.001'"), (None, "NoneType None")):
        with pytest.raises(TypeError, match=rf"^dt: expected a real number, got {shown}$"):
            m.npid_step(*p, m.NpidState(), _input(m), dt)
        with pytest.raises(TypeError, match=r"^dt: expected a real number"):
            m.dobc_step(*p, m.DobcState(), _input(m), dt)
        with pytest.raises(TypeError, match=r"^dt: expected a real number"):
            m.mom_step(*p, m.MomState(), _input(m), dt)
    with pytest.raises(TypeError, match=r"^state: expected a NpidState \(with \.int_e\), got DobcState$"):
        m.npid_step(*p, m.DobcState(), _input(m), 1e-3)
    with pytest.raises(TypeError, match=r"^state: expected a DobcState \(with \.z\), got NpidState$"):
        m.dobc_init(*p, m.NpidState(), _input(m))
    with pytest.raises(TypeError, match=r"^state: expected a MomState \(with \.m\), got DobcState$"):
        m.mom_step(*p, m.DobcState(), _input(m), 1e-3)
    with pytest.raises(TypeError, match=r"^inp: expected an Input \(theta, dtheta, yd, dyd, ddyd\), got list$"):
        m.mpc_step(*p, [[0.1, 0.2]] * 5)


def test_real_numbers_of_any_container_give_the_same_u_and_nonfinite_keeps_its_code(module):
    m = module
    p = _args(m)
    code, want, clipped = m.mpc_step(*p, _input(m))
    assert code == m.OK and want.shape == (2,) and clipped == 0
    for theta in ((0.1, 0.2), np.array([0.1, 0.2]), [np.float64(0.1), 0.2]):
        assert np.array_equal(m.mpc_step(*p, _input(m, theta=theta))[1], want)
    code, u, _ = m.mpc_step(*p, _input(m, theta=np.array([0.1, 0.2], dtype=np.float32), dyd=[0, 0]))
    assert code == m.OK and np.allclose(u, want, rtol=1e-6)
    assert m.mpc_step(*p, _input(m, theta=[float("nan"), 0.2])) == (m.ENONFINITE, None, None)
    assert m.npid_step(*p, m.NpidState(), _input(m), float("nan")) == (m.EDT, None, None)
    assert m.npid_step(*p, m.NpidState(), _input(m), 1)[0] == m.OK  # an int dt is a real number



def test_the_fast_argument_check_refuses_what_the_named_checks_refuse(module):
    """The steps check lists of N floats at once (issue 23): a nan or inf anywhere among the
    inputs and the state is ENONFINITE with the state untouched, an inf and a -inf that cancel
    in the check's sum included; finite entries whose sum overflows are still finite."""
    m = module
    p = _args(m)
    nan, inf = float("nan"), float("inf")
    for field, bad in (("theta", [nan, 0.2]), ("ddyd", [0.0, inf]), ("yd", [inf, -inf])):
        for make, step in ((m.NpidState, m.npid_step), (m.DobcState, m.dobc_step), (m.MomState, m.mom_step)):
            state = make()
            before = {k: list(getattr(state, k)) for k in state.__slots__}
            assert step(*p, state, _input(m, **{field: bad}), 1e-3) == (m.ENONFINITE, None, None)
            assert {k: list(getattr(state, k)) for k in state.__slots__} == before
    state = m.NpidState()
    state.int_e = [0.0, nan]
    assert m.npid_step(*p, state, _input(m), 1e-3) == (m.ENONFINITE, None, None)
    assert m.npid_step(*p, m.NpidState(), _input(m), inf) == (m.EDT, None, None)
    assert m.npid_step(*p, m.NpidState(), _input(m), -1e-3) == (m.EDT, None, None)
    assert m._finite([1e308, 1e308], [1e308]) and not m._finite([inf, -inf]) and not m._finite([1.0], [nan])
    code, u, _ = m.npid_step(*p, m.NpidState(), _input(m), 1e-3)
    assert code == m.OK and type(u) is np.ndarray and u.shape == (2,)

def test_runtime_parameters_are_checked_too(runtime):
    m = runtime
    params = m.Params()
    params.m1 = "0.361"
    with pytest.raises(TypeError, match=r"^params\.m1: expected a real number, got str '0\.361'$"):
        m.mpc_step(params, _input(m))
    params = m.Params()
    params.u_max = [12.0]
    with pytest.raises(ValueError, match=r"^params\.u_max: expected shape \(2,\), got shape \(1,\)$"):
        m.npid_step(params, m.NpidState(), _input(m), 1e-3)
    with pytest.raises(TypeError, match=r"^params: expected a Params, got dict$"):
        m.gains({}, [0.1, 0.2])
    params = m.Params()
    params.m1 = None
    with pytest.raises(TypeError, match=r"^params\.m1: expected a real number, got NoneType None$"):
        m.forward_dynamics(params, [0.1, 0.2], [0.0, 0.0], [1.0, 0.0], [0.0, 0.0])
    with pytest.raises(TypeError, match=r"^params: expected a Params, got dict$"):
        m.input_matrix({})
