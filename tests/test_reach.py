"""derive.codegen.reach: which kernel inputs need no finiteness check of their own in the C glue.

An input port is covered by an output when a non-finite value in any of its entries makes that
output non-finite (propagation through the printed operations) and the output really depends on
the entry (a Jacobian column, so that flags assuming finite math cannot rewrite it away). The
steps then check only their results (templates/c/arm.c.jinja); tests/test_finite_math.py runs
the whole error contract under ten flag sets that assume finite math.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

import derive
from derive.codegen.casadi_bridge import to_function
from derive.codegen.kernels import ParamsMode, kernel_specs
from derive.codegen.reach import carried, covered, generic_point
from derive.model.examples import planar_chain


def _function(name, ins, outs):
    xs = [ca.SX.sym(n, k) for n, k in ins]
    return ca.Function(name, xs, [o(*xs) for o in outs], [n for n, _ in ins], [f"y{i}" for i in range(len(outs))],
                       {"cse": True})


def test_a_denominator_is_not_covered_a_numerator_is():
    f = _function("quotient", [("x", 1), ("y", 1)], [lambda x, y: x / y])
    assert covered(f) == {"y0": ("x",)}
    # what the rule stands for: a non-finite denominator can give a finite result
    assert float(f(1.0, math.inf)) == 0.0
    assert math.isnan(float(f(math.nan, 2.0)))


def test_fmin_and_a_comparison_carry_nothing():
    f = _function("clamp", [("x", 1), ("y", 1)], [lambda x, y: ca.fmin(x, 1.0) + ca.if_else(y < 0, 1.0, 2.0)])
    assert covered(f) == {"y0": ()}
    # what the rule stands for: fmin drops a NaN, a comparison turns it into a branch
    assert float(f(math.nan, 0.5)) == 3.0 and float(f(0.5, math.nan)) == 2.5


def test_every_entry_of_a_port_must_reach_the_output():
    # x[1] only reaches the second output
    f = _function("split", [("x", 2)], [lambda x: 3 * x[0], lambda x: x[0] * x[1]])
    assert covered(f) == {"y0": (), "y1": ("x",)}
    assert carried(f) == [[0b01], [0b11]]


def test_an_entry_that_cancels_is_not_covered():
    # (x + 1)(x - 1) - x^2 + y carries x structurally; in real arithmetic it does not depend on
    # x, so -ffast-math may rewrite x away: the dependence test refuses it
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    g = ca.Function("cancel", [x, y], [(x + 1) * (x - 1) - x * x + y], ["x", "y"], ["y0"])
    assert carried(g) == [[0b11]]
    assert covered(g) == {"y0": ("y",)}


def test_sine_and_cosine_carry_their_argument():
    f = _function("trig", [("q", 1)], [lambda q: ca.sin(q) + 2 * ca.cos(q)])
    assert covered(f) == {"y0": ("q",)}


def test_generic_point_takes_given_values_and_a_small_dt():
    f = _function("mixed", [("p", 2), ("dt", 1), ("x", 3)], [lambda p, dt, x: p[0] * dt + x[0]])
    point = generic_point(f, {"p": [4.0, 5.0]})
    assert point[0].tolist() == [4.0, 5.0] and point[1].tolist() == [1e-3]
    assert len(set(point[2].tolist())) == 3 and all(0.3 <= v <= 0.7 for v in point[2])


@pytest.fixture(scope="module")
def chain3():
    return derive.derive(planar_chain(3, gravity=9.81))


def test_the_laws_cover_every_input_of_their_steps(chain3):
    """eq. (15, 27, 34): u* and the composite and PID laws read every input and state entry."""
    fs = {s.name: to_function(s) for s in kernel_specs(chain3, ParamsMode.BAKED)}
    everything = ("theta", "dtheta", "yd", "dyd", "ddyd")
    assert covered(fs["mpc"])["u"] == everything
    assert covered(fs["npid"])["u"] == everything + ("int_e",)
    assert covered(fs["dobc"])["u"] == everything + ("z",)
    assert covered(fs["mom"])["u"] == everything + ("m",)
    # dhat = B^-1 (z + W theta') (eq. 22) reads neither theta nor the reference
    assert covered(fs["dhat"])["dhat"] == ("dtheta", "z")
    # z(0) = -W (yd' + K2 e(0)): theta' cancels in B dhat(0) - W theta'(0) (eq. 30)
    assert "dtheta" not in covered(fs["dobc_init"])["z0"]


def test_a_covered_entry_makes_the_output_nonfinite(chain3):
    """The proof checked by evaluation: NaN, Inf and -Inf in each entry of each covered port of
    every kernel give a non-finite entry of the output (CasADi evaluates in IEEE double)."""
    for spec in kernel_specs(chain3, ParamsMode.BAKED):
        f = to_function(spec)
        point = generic_point(f)
        for out, ports in covered(f).items():
            o = [f.name_out(k) for k in range(f.n_out())].index(out)
            for port in ports:
                p = [f.name_in(k) for k in range(f.n_in())].index(port)
                for i in range(f.nnz_in(p)):
                    for bad in (math.nan, math.inf, -math.inf):
                        args = [a.copy() for a in point]
                        args[p][i] = bad
                        y = np.asarray(f.call(args)[o], dtype=float)
                        assert not np.all(np.isfinite(y)), (spec.name, out, port, i, bad)


def test_the_glue_checks_only_what_no_result_covers(tmp_path, chain3):
    from derive.codegen.emit import write_tree
    from derive.codegen.files import generate_files

    write_tree(tmp_path, generate_files(chain3, b"", "double", ParamsMode.BAKED))
    glue = next(tmp_path.rglob("chain3.c")).read_text()
    step = glue[glue.index("int chain3_npid_step("):]
    step = step[:step.index("\n}\n")]
    assert "input_finite" not in step and "finite_all(in->" not in step
    assert "finite_all(v, N) || !finite_all(step, N)" in step
    estimate = glue[glue.index("int chain3_dobc_estimate("):]
    estimate = estimate[:estimate.index("\n}\n")]
    assert ("finite_all(in->theta, N) && finite_all(in->yd, N) && finite_all(in->dyd, N) "
            "&& finite_all(in->ddyd, N)") in estimate
