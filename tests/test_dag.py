"""Expression-DAG walks (derive.dynamics.dag) build exactly what SymPy's tree
walks build, visiting each distinct subexpression once (issue 11.6)."""
from __future__ import annotations

import pytest
import sympy as sp

import derive
from derive.dynamics import dag
from derive.dynamics.equations import derive_dynamics
from derive.model.examples import planar_chain


def _tree_size(exprs) -> int:
    sizes: dict = {}

    def size(e):
        if e not in sizes:
            sizes[e] = 1 + sum(size(a) for a in e.args)
        return sizes[e]
    return sum(size(e) for e in exprs)


def test_xreplace_jacobian_and_free_symbols_equal_sympys_on_a_4_link_chain():
    d = derive.derive(planar_chain(4, gravity=9.81))
    npid = d.npid
    rule = dict(d.values)
    for m in (d.dynamics.J, d.dynamics.G, npid.u_npid):
        assert dag.matrix_xreplace(m, rule) == m.xreplace(rule)
        assert dag.Substitution(rule)(m) == m.xreplace(rule)
        assert dag.free_symbols(list(m)) == m.free_symbols
    s = d.dynamics.sym
    for v in (s.e, s.de, s.int_e):
        assert dag.jacobian(npid.u_npid, v) == npid.u_npid.jacobian(v)


def test_walks_visit_each_distinct_subexpression_once_on_an_8_link_chain(monkeypatch):
    """G of the 8-link chain: tens of thousands of tree nodes (the old planar
    recursion's: 1.6 million), a few hundred distinct objects."""
    dyn = derive_dynamics(planar_chain(8, gravity=9.81))
    G = list(dyn.G)
    assert _tree_size(G) > 4 * 10 ** 4
    visits = []
    walk = dag._postorder

    def counting(roots, done, skip=None):
        for e in walk(roots, done, skip):
            visits.append(e)
            yield e
    monkeypatch.setattr(dag, "_postorder", counting)
    memo = dag.Memo()
    dag.free_symbols(G, memo)
    assert len(visits) == len(memo) < 1000  # once per object, and there are few
    visits.clear()
    out = dag.Substitution(dict(dyn.values))(dyn.G)
    assert len(visits) < 1000 and out.free_symbols <= set(dyn.sym.theta + dyn.sym.dtheta)
    visits.clear()
    J = dag.jacobian(dyn.G, dyn.sym.dtheta[:1])
    assert 0 < len(visits) < 2000 and J.shape == (8, 1)


def test_values_put_in_keep_each_sum_shared_same_values_fewer_operations():
    """A parameter's value in front of a shared sum (a body's mass times its
    acceleration) multiplies the sum instead of being distributed over its
    terms: the Derivation's numeric J and bias have the values of SymPy's
    xreplace at a state, and far fewer operations after CSE (the Panda's bias:
    about 1,650 distributed, about 1,000 kept)."""
    from pathlib import Path

    from derive.dynamics.identities import count_ops_cse
    from derive.model.spec import load_arm
    dyn = derive_dynamics(load_arm(Path(__file__).parent / "data" / "urdf" / "panda.toml"))
    rule = dict(dyn.values)
    kept = dag.Substitution(rule, keep_sums=True)(dyn.bias)
    spread = dag.Substitution(rule)(dyn.bias)
    assert count_ops_cse(list(kept)) < 0.7 * count_ops_cse(list(spread))
    s = dyn.sym
    point = {x: sp.Float(0.1 * (k % 5) - 0.2, 30) for k, x in enumerate(s.theta + s.dtheta)}
    a = dag.Substitution(point)(kept)
    b = dag.Substitution(point)(spread)
    assert max(abs(x - y) for x, y in zip(a, b)) < 1e-20
    two = sp.Symbol("m") * (sp.Symbol("x") + sp.Symbol("y"))
    assert dag.xreplace(two, {sp.Symbol("m"): sp.Rational(3, 2)}, keep_sums=True).is_Mul
    assert dag.xreplace(two, {sp.Symbol("m"): sp.Rational(3, 2)}).is_Add


def test_operation_count_takes_a_rational_constant_as_one_literal():
    """count_ops_cse counts what generated code computes: 3/4 x is one
    multiplication by the literal 0.75 (SymPy's count_ops alone: MUL and DIV),
    x + 1/3 one addition; shared x y once."""
    from derive.dynamics.identities import count_ops_cse
    x, y = sp.symbols("x y")
    assert sp.count_ops(sp.Rational(3, 4) * x) == 2
    assert count_ops_cse([sp.Rational(3, 4) * x]) == 1
    assert count_ops_cse([x + sp.Rational(1, 3)]) == 1
    assert count_ops_cse([sp.Rational(3, 4) * x * y + 1, 2 * x * y]) == 4


def test_times_multiplies_a_small_matrix_into_large_expressions_without_asking_if_they_are_zero():
    """derive.dynamics.dag.times (B u*, B dhat(0), B^-1 G in derive.codegen's kernels and reference, eq. 27, 30):
    SymPy's matrix product asks every entry whether it is zero, a query that on the xArm6's u* ran for
    minutes (generate 386 s, fmu --plant past 900 s); times gives the same products without asking."""
    from derive.dynamics.dag import times

    class Unaskable(sp.Symbol):
        def _eval_is_zero(self):
            raise AssertionError("is_zero asked")

    a, b = Unaskable("a"), Unaskable("b")
    v = sp.Matrix([a + 2 * b, a * b])
    with pytest.raises(AssertionError, match="is_zero asked"):
        sp.Matrix([[2, 0], [0, 1]]) * v
    B = sp.Matrix([[2, 0], [0, 1]])
    assert times(B, v) == sp.Matrix([2 * (a + 2 * b), a * b])
    assert times(sp.Matrix([[1, 3], [0, sp.Symbol("g")]]), v) == sp.Matrix([a + 2 * b + 3 * a * b,
                                                                            sp.Symbol("g") * a * b])
