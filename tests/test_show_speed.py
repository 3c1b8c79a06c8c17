"""What makes ``derive show`` cheaper (issue 23: my3 from a cold cache under 1 s of CPU) computes what
was computed before: the same sample-time search decisions, the same printed text, the same BLAS
threads. Each shortcut is held against the way it replaces."""
from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derive
from derive.cli import show
from derive.cli.notation import TextPrinter
from derive.control import sampling
from derive.control.mpc import gains, tbar
from derive.control.sampling.radius import spectral_radius

DATA = Path(__file__).resolve().parent / "data"
REPO = Path(__file__).resolve().parents[1]


@functools.lru_cache(maxsize=None)
def _my3() -> derive.Derivation:
    return derive.derive(derive.load_arm(DATA / "my3.toml"))


@functools.lru_cache(maxsize=None)
def _linear(form: str) -> dict:
    d = _my3()
    pts = sampling.operating_points(d)
    return sampling._loop(d).linearise(form, np.array([q for q, _ in pts]), np.array([dq for _, dq in pts]))


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.uint64), b.view(np.uint64))


@pytest.mark.parametrize("form, observer", [("mpc", "explicit"), ("dobc", "explicit"), ("npid", "implicit"),
                                            ("dobc", "implicit"), ("mom", "explicit")])
@pytest.mark.parametrize("dt", [sampling.DT_MIN, 1e-3, 0.2])
def test_eigenvalues_first_finds_the_same_radii_at_or_above_1_as_the_usual_way(form, observer, dt):
    """spectral_radius(eigen_first=True) against the usual way (stable_bound, then the eigenvalues of
    what it does not prove): the same matrices >= 1 with the same radii, every value < 1 on the same
    matrices; at 0.2 s some of my3's loops are unstable (the usual way's result, bit for bit)."""
    L = _linear(form)
    M = sampling._transition(sampling._loop(_my3()), form, observer, dt, L)
    usual = spectral_radius(M, exact=False)
    first = spectral_radius(M, exact=False, eigen_first=True)
    assert np.array_equal(usual >= 1.0, first >= 1.0)
    assert _same_bits(usual[usual >= 1.0], first[first >= 1.0])
    if (usual >= 1.0).any():
        assert _same_bits(usual, first)
    if dt == 0.2:
        assert (usual >= 1.0).any()


def test_the_search_subsets_are_numpys_union():
    rng = np.random.default_rng(5)
    for _ in range(50):
        P = int(rng.integers(1, 800))
        parts = [rng.integers(0, P, int(rng.integers(0, 60))) for _ in range(2)]
        assert _same_bits(sampling._union(P, *parts), np.union1d(*parts).astype(np.intp))


def test_the_gain_formulas_are_factored_as_sympy_factors_them():
    """derive show prints k1(T1, T2), k2(T1, T2) (eq. 16-18) as gains returns them: factored."""
    for k in gains():
        assert sp.srepr(sp.factor(k)) == sp.srepr(k)


def test_the_gain_formulas_are_the_trees_sympy_factor_gives_for_the_quotients_of_eq18():
    """gains builds k1 = Tbar31 / Tbar33, k2 = Tbar32 / Tbar33 (eq. 16-18) in closed form: the same
    SymPy trees as sp.factor of the quotients (what it computed before), term for term."""
    for k, j in zip(gains(), (1, 2)):
        assert sp.srepr(k) == sp.srepr(sp.factor(tbar(3, j) / tbar(3, 3)))


def test_a_shown_entry_printed_as_its_terms_reads_as_doprint():
    d = _my3()
    pr = TextPrinter(show._names(d).text, True, show.DIGITS)
    for e in show.entries(d):
        value = show.tidy(e, False, d.dynamics.angles).value
        for x in (value if isinstance(value, sp.MatrixBase) else [value] if value is not None else []):
            assert " ".join(pr.terms(sp.sympify(x))) == pr.doprint(x), e.key


def _run(code: str) -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                             "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_show_of_a_planar_arm_loads_no_urdf_reader_synthesis_numpy_ma_threadpoolctl_or_difflib():
    code = ("import contextlib, io, sys\nfrom derive.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    assert main(['show', {str(DATA / 'my3.toml')!r}, '--no-cache']) == 0\n"
            "print(sorted(m for m in ('derive.model.urdf', 'derive.model.dh', 'derive.control.certificate.synthesis', "
            "'numpy.ma', 'threadpoolctl', 'difflib') if m in sys.modules))")
    assert _run(code) == "[]"


def test_blas_runs_on_one_thread_when_numpy_comes_after_the_commands_setting():
    """derive show imports NumPy after derive.cli._one_blas_thread (no threadpoolctl then): OpenBLAS
    reads the variables as it loads."""
    code = ("from derive import cli\nimport sys\nassert 'numpy' not in sys.modules\n"
            "with cli._one_blas_thread():\n    import numpy\n    from threadpoolctl import threadpool_info\n"
            "    print(sorted({p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas'}))")
    assert _run(code) == "[1]"


def _listed_by_rglob(root: Path) -> list[Path]:
    return [p for p in sorted(root.rglob("*"))
            if p.is_file() and "__pycache__" not in p.parts and p.suffix not in (".pyc", ".so")]


def test_the_fingerprinted_files_are_those_rglob_lists_in_its_order(tmp_path):
    """derive.cache.code_files (os.walk, __pycache__ not entered) lists what the fingerprint hashed
    before: the package, the templates and a tree with bytecode, a .so, nested folders, a symlink."""
    from derive.cache import code_files
    from derive.paths import PACKAGE, TEMPLATES

    for root in (PACKAGE, TEMPLATES):
        assert code_files(root) == _listed_by_rglob(root)
    for rel in ("a.py", "b/__pycache__/a.cpython-311.pyc", "b/c.py", "b/c.so", "b-c/x.txt", "b/d/e.j2", "Z.py"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(rel)
    (tmp_path / "link.py").symlink_to(tmp_path / "a.py")
    (tmp_path / "dirlink").symlink_to(tmp_path / "b", target_is_directory=True)
    assert code_files(tmp_path) == _listed_by_rglob(tmp_path)
    assert len(code_files(tmp_path)) == 6


def test_the_console_process_of_show_runs_without_the_cycle_collector_and_a_caller_keeps_its_own(capsys):
    """derive.cli.NO_CYCLE_COLLECTOR: only the process's own command line (argv None) turns the
    collector off and freezes at the end; main(argv) from a caller (the tests) leaves gc alone."""
    import gc

    from derive.cli import main

    frozen = gc.get_freeze_count()
    assert main(["show", str(DATA / "my3.toml"), "--no-cache"]) == 0
    assert gc.isenabled() and gc.get_freeze_count() == frozen
    capsys.readouterr()
    code = ("import contextlib, gc, io, sys\nfrom derive.cli import main\n"
            f"sys.argv = ['derive', 'show', {str(DATA / 'my3.toml')!r}, '--no-cache']\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n    assert main() == 0\n"
            "print(gc.isenabled(), gc.get_freeze_count() > 0)")
    assert _run(code) == "False True"


def test_the_zero_order_holds_shared_by_the_forms_searches_give_the_limits_computed_anew(monkeypatch):
    """limits() hands its forms' searches one store of zero-order holds per (dt, A, Bu)
    (derive.control.sampling.sample_limit's ``holds``): on my3 they ask for the same ones (A, Bu the
    same bits for MPC, DOBC and NPID), and every limit, raw value and worst point is the one found when
    each is computed anew (a store per search)."""
    asked = []
    real = sampling.zoh
    monkeypatch.setattr(sampling, "zoh", lambda L, dt: asked.append(dt) or real(L, dt))
    d = derive.derive(derive.load_arm(DATA / "my3.toml"))
    shared = {o: sampling.limits(d, o) for o in sampling.OBSERVERS}
    computed = len(asked)
    original = sampling.sample_limit
    monkeypatch.setattr(sampling, "sample_limit", lambda *a, holds=None, **k: original(*a, **k))
    again = derive.derive(derive.load_arm(DATA / "my3.toml"))
    anew = {o: sampling.limits(again, o) for o in sampling.OBSERVERS}
    assert anew == shared
    assert (len(asked) - computed) - computed >= 10   # computed anew what was shared (my3: 23 of 134)


def test_width_counts_an_ascii_text_by_its_length_as_it_counts_every_text():
    """derive.cli.notation.width's shortcut: no ASCII character is a combining mark."""
    import unicodedata

    from derive.cli.notation import width

    assert all(unicodedata.combining(chr(c)) == 0 for c in range(128))
    for text in ("", "J12 = 0.25 cos(θ₂)", "θ̇₁ + ė(0)", "ascii only, 0.5 * x", "a\u0301b"):
        assert width(text) == sum(0 if unicodedata.combining(ch) else 1 for ch in text)


def test_the_linearisation_keeps_what_every_form_shares_and_gives_each_the_bits_of_its_own_run():
    """SampledLoop.linearise keeps J^-1 B, -J^-1 dG/d theta', dr per points and d theta''/d theta per
    theta'' (derive.control.sampling.linear_loop): each form's arrays, after the others', are those of a loop that
    linearises that form alone; MPC, DOBC and NPID share theta'' on my3 (kept), MOM does not."""
    from derive.control.sampling.linear_loop import SampledLoop

    d = _my3()
    pts = sampling.operating_points(d)
    Q, DQ = np.array([q for q, _ in pts]), np.array([dq for _, dq in pts])
    shared = SampledLoop(d)
    kept = []
    for form in sampling.FORMS:
        mine = shared.linearise(form, Q, DQ)
        kept.append(shared._accel[0])
        alone = SampledLoop(d).linearise(form, Q, DQ)
        assert mine.keys() == alone.keys()
        assert all(_same_bits(mine[k], alone[k]) for k in mine), form
    assert kept[0] == kept[1] == kept[2] != kept[3]


def test_the_kept_zero_order_holds_drop_the_oldest_beyond_their_budget(monkeypatch):
    import importlib

    zoh = importlib.import_module("derive.control.sampling.zoh")   # the package's name zoh is the function

    L = {"A": np.zeros((10, 4, 4)), "Bu": np.zeros((10, 4, 2))}
    each = 10 * 6 * 6 * 8 + L["A"].nbytes + L["Bu"].nbytes      # an exp of 10 stacked 6 x 6, and the key's bytes
    monkeypatch.setattr(zoh, "HOLDS_BYTES", 3 * each)
    holds = {}
    for dt in (1.0, 2.0, 3.0, 4.0, 5.0):
        holds[(dt, L["A"].shape, L["A"].tobytes(), L["Bu"].tobytes())] = zoh.zoh(L, dt)
        zoh.bound(holds)
    assert [k[0] for k in holds] == [3.0, 4.0, 5.0]
