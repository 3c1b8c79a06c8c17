"""``derive show``: readable at 100 columns, the paper's notation, labelled LaTeX (issue 15.8).

The entries are shown in the Fourier normal form of
:func:`derive.dynamics.identities.fourier_form`; the tests prove that form equal
to the derivation's own matrices (so nothing shown differs from what is generated)
and pin the my3 arm's inertia matrix to the values worked out by hand.
"""
from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

import pytest
import sympy as sp

import derive
from derive.cli import show
from derive.cli.notation import width
from derive.dynamics.identities import fourier_form, is_zero

DATA = Path(__file__).resolve().parent / "data"
REPO = Path(__file__).resolve().parents[1]


@functools.lru_cache(maxsize=None)
def my3() -> derive.Derivation:
    """The 3-link vertical arm of issue 15 (0.35/0.30/0.15 m, geared motors, gripper)."""
    return derive.derive(derive.load_arm(DATA / "my3.toml"))


def test_fourier_form_is_the_derivation_itself_entry_by_entry():
    d = my3()
    for name in ("J", "G", "N", "P", "D"):
        for x in getattr(d, name):
            assert is_zero(fourier_form(x, d.theta) - x, d.theta), name


def test_fourier_form_turns_products_into_sums_of_angles():
    a, b, v = sp.symbols("a b v", real=True)
    expr = 2 * sp.cos(a) * sp.cos(b) - 2 * sp.sin(a) * sp.sin(b) + v * sp.sin(a) ** 2
    assert sp.expand(fourier_form(expr, (a, b)) - (2 * sp.cos(a + b) + v / 2 - v * sp.cos(2 * a) / 2)) == 0


def test_fourier_form_of_high_powers_and_negative_frequencies_matches_sympy():
    # the Laurent form's offsets (cos(a - 2 b): negative exponents) and I^e with e up to 5
    # (sin^5, products of four sines: the sign of I^2 and I^4), against SymPy's own rewrite
    a, b, c, d, v = sp.symbols("a b c d v", real=True)
    expr = (sp.sin(a) ** 5 - 3 * v * sp.sin(a) * sp.sin(b) * sp.sin(c) * sp.sin(d) + sp.cos(a - 2 * b) ** 3 * v ** 2
            + sp.Rational(7, 3) * sp.sin(2 * a + b) * sp.cos(c) ** 2 - sp.Rational(1, 5))
    form = fourier_form(expr, (a, b, c, d))
    assert sp.simplify(sp.expand_trig(form - expr)) == 0
    assert all(t.base == v for t in sp.preorder_traversal(form) if isinstance(t, sp.Pow))   # sums of single waves


@pytest.mark.parametrize("expr, match", [("a + sin(a)", "a appears outside sin/cos"),
                                         ("sin(a/2)", "integer combination of the angles"),
                                         ("exp(a)", "expected a polynomial in sin/cos"),
                                         ("1/(v + sin(a))", "expected a polynomial in sin/cos")])
def test_fourier_form_refuses_what_is_not_a_trigonometric_polynomial(expr, match):
    a, v = sp.symbols("a v", real=True)
    with pytest.raises(ValueError, match=match):
        fourier_form(sp.sympify(expr, locals={"a": a, "v": v}), (a,))


def test_show_my3_fits_100_columns_in_the_papers_notation():
    text = show.render_text(my3())
    lines = text.splitlines()
    assert max(width(line) for line in lines) <= 100
    assert "  J₁₁ = 0.3775 + 0.2415·cos(θ₂) + 0.036·cos(θ₃) + 0.042·cos(θ₂ + θ₃)" in lines
    assert "  J₃₃ = 0.008275" in lines and "J₂₁" not in text          # symmetric: upper triangle
    assert "  ⎡ 1  0    0   ⎤" in lines                                 # B = diag(gear Kt / R)
    assert "θ̇₁·θ̇₂·sin(θ₂)" in text and "ÿd₁" in text and "ė₁(0)" in text and "e₁(0)" in text
    for ascii_name in ("dtheta", "de0", "e0_", "ddyd", "θ₁ ₁"):
        assert ascii_name not in text


def test_show_exact_and_ascii():
    exact = show.render_text(my3(), exact=True).splitlines()
    assert "  J₁₁ = 151/400 + (483/2000)·cos(θ₂) + (9/250)·cos(θ₃) + (21/500)·cos(θ₂ + θ₃)" in exact
    plain = show.render_text(my3(), unicode=False)
    assert plain.isascii() and max(len(line) for line in plain.splitlines()) <= 100
    assert "  J[1,1] = 0.3775 + 0.2415*cos(theta2) + 0.036*cos(theta3) + 0.042*cos(theta2 + theta3)" in plain
    assert "dtheta1*dtheta2*sin(theta2)" in plain and "de1(0)" in plain


def test_show_quotients_and_lumped_parameters_of_the_default_arm(paper):
    text = show.render_text(paper)
    # L = W J^-1 (eq. 24); det J = j1 j3 - j2^2 + (j3 X... ) in cos(2 theta2) with a unit constant term
    assert "/(1 - 0.211855·cos(2·θ₂))" in text
    assert "X = 0.0405042   lumped inertia parameter (eq. a6)" in text
    assert "max |θ̇₂| for (26) = 24.6888   w1/X [rad/s] (eq. 26)" in text


def test_show_latex_labels_every_quantity_with_proper_symbols():
    d = my3()
    tex = show.render_latex(d)
    assert r"\dot{\theta}_{1} \dot{\theta}_{2} \sin{\left(\theta_{2} \right)}" in tex
    assert r"\dot{e}_{1}(0)" in tex and r"\ddot{y}_{d,1}" in tex and r"\hat{d}" in tex
    body = [line for line in tex.splitlines() if not line.startswith("%")]      # comments name them in ASCII
    assert not [line for line in body if "dtheta" in line or "de0" in line or "ddyd" in line]
    keys = [e.key for e in show.entries(d)]
    assert [tex.count(rf"\label{{derive:my3:{k}}}") for k in keys] == [1] * len(keys)
    envs = [tex.count(rf"\{x}{{{env}}}") for x in ("begin", "end") for env in ("equation", "align")]
    assert envs[0] + envs[1] == envs[2] + envs[3] == len(keys)
    assert r"J_{11} &= 0.3775 + 0.2415 \cos{\left(\theta_{2} \right)}" in tex


@pytest.mark.parametrize("encoding, name", [("utf-8", "J(θ)"), ("ascii", "J(theta)")])
def test_cli_show_follows_the_terminal_encoding(encoding, name, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "derive", "show", str(DATA / "my3.toml")], cwd=tmp_path,
                          capture_output=True, text=True, encoding=encoding, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(REPO), "PYTHONIOENCODING": encoding})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("arm my3: 3 joints") and f"\n{name}   inertia matrix" in proc.stdout
