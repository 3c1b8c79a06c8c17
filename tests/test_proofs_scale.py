"""``derive check`` at seven joints (issue 19 item 2): exact, sound and fast.

The control obligations are decided over placeholders J_ij = J_ji, G_i
(derive.control.opaque) and only for the Derivation they were inlined into; the
dynamics' own identities (J' - 2C skew, energy, the RNEA law = J a + G of eq. 15)
are decided exactly on the torus of the angles in FLINT (derive.proofs.torus).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import sympy as sp

from derive.control.pipeline import derive
from derive.model.spec import load_arm
from derive.proofs import dynamics as proofs_dynamics, project as proofs_project
from derive.proofs.core import Status, run
from derive.proofs.exact import Undecidable
from derive.proofs.torus import TooLarge, Torus

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def panda():
    return derive(load_arm(str(DATA / "urdf" / "panda.toml")))


def test_torus_zero_test_is_canonical_modulo_the_circle():
    a, b, x = sp.symbols("a b x", real=True)
    T = Torus([a, b], [x])
    assert T.is_zero(T(sp.sin(a + b) ** 2 + sp.cos(a + b) ** 2 - 1))
    assert T.is_zero(T(sp.sin(2 * a) - 2 * sp.sin(a) * sp.cos(a)))
    assert T.is_zero(T(sp.cos(a - 2 * b) - sp.cos(a) * sp.cos(2 * b) - sp.sin(a) * sp.sin(2 * b)))
    assert not T.is_zero(T(sp.sin(a) * x))                     # a refutation, not a doubt
    assert not T.is_zero(T(sp.sin(a) ** 2 - sp.Rational(1, 2)))
    # d/da sin(a)^2 x = 2 sin cos x; d/dt through the chain rule
    assert T.is_zero(T.diff(T(sp.sin(a) ** 2 * x), a) - T(2 * sp.sin(a) * sp.cos(a) * x))
    with pytest.raises(Undecidable, match="outside sin/cos"):
        T(a * x)
    with pytest.raises(Undecidable):
        T(sp.sin(sp.Rational(3, 10)) * x)                       # sin of a constant: not in the ring


def test_convert_keeps_only_its_roots_and_agrees_with_the_one_by_one_conversion():
    """convert drops a subexpression once its last parent is converted (12 joints: the Coriolis
    matrix's 26 million terms of intermediates, 1.9 GB, down to its own 5.6 million); the
    polynomials are those of the memoised one-at-a-time conversion."""
    a, b, x, y = sp.symbols("a b x y", real=True)
    shared = (sp.sin(a) * x + sp.cos(b) * y) ** 2
    exprs = [shared * x + 3, shared * sp.cos(a + b), (shared + x) * shared, x * y]
    T = Torus([a, b], [x, y])
    got = T.convert(exprs)
    assert set(T._memo) == set(exprs)                  # the roots only: every intermediate was released
    U = Torus([a, b], [x, y])
    assert all(T.is_zero(g - U(e)) for g, e in zip(got, exprs))
    assert T.convert(exprs[:2]) == got[:2]             # the roots are reused, not reconverted
    with pytest.raises(Undecidable, match="outside sin/cos"):
        T.convert([a * x])
    small = Torus([a, b], [x, y], total=10)   # the terms held at once: past the budget, TooLarge, memo emptied
    with pytest.raises(TooLarge, match="held at once"):
        small.convert(exprs)
    assert not small._memo


def test_eq12_skew_energy_and_eq15_rnea_law_proved_for_the_7_joint_panda(panda):
    """The dynamics' identities, decided exactly for a 7-joint arm (SymPy's fraction field
    took over 10 minutes here; the torus ring takes seconds)."""
    res = {r.obligation.id: r.outcome for r in run(proofs_dynamics.OBLIGATIONS, panda)}
    for key in ("skew-symmetry", "energy", "rnea-law"):
        assert res[key].status is Status.PROVED, (key, res[key].detail)
    assert "n = 7" in res["skew-symmetry"].detail and "n = 7" in res["rnea-law"].detail


def test_control_obligations_proved_over_placeholders_for_the_panda(panda):
    res = {r.obligation.id: r.outcome for r in run(proofs_project.OBLIGATIONS, panda)}
    assert all(o.status is Status.PROVED for o in res.values()), {k: o.detail for k, o in res.items()}
    assert proofs_project.FORMAL in res["pid-gains"].detail


def test_eq15_rnea_law_refuted_when_the_generated_law_is_wrong(panda):
    """A law that drops one joint's gravity is not eq. (15): refuted, with both sides shown."""
    wrong = panda.mpc.u_star_rnea.copy()
    wrong[6] = wrong[6] - sp.Symbol("g", nonnegative=True)
    bad = dataclasses.replace(panda, mpc=dataclasses.replace(panda.mpc, u_star_rnea=wrong))
    out = run([o for o in proofs_dynamics.OBLIGATIONS if o.id == "rnea-law"], bad)[0].outcome
    assert out.status is Status.REFUTED and "u*[7]" in out.detail


def test_a_changed_copy_is_decided_on_its_own_matrices_not_its_formal_one(panda):
    """formal_first uses the placeholder form only for the Derivation inlined from it: a copy
    with a field replaced falls back to its own matrices (so a wrong K1 is refuted)."""
    assert panda.formal_view is panda.formal
    assert dataclasses.replace(panda, K1=panda.K1).formal_view is None
    my3 = derive(load_arm(str(DATA / "my3.toml")))
    wrong = dataclasses.replace(my3, K1=my3.K1 * sp.Rational(101, 100))
    assert wrong.formal_view is None
    out = run([o for o in proofs_project.OBLIGATIONS if o.id == "u*-loop"], wrong)[0].outcome
    assert out.status is Status.REFUTED
