"""Expression-DAG walks (derive.dynamics.dag) build exactly what SymPy's tree
walks build, visiting each distinct subexpression once (issue 11.6)."""
from __future__ import annotations

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
