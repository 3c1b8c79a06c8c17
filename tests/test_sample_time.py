"""The largest sample time of the generated controllers (issue 12, item 4).

The limits come from the linearised sampled loop (derive.control.sampling); the tests hold them
against closed-loop simulations of the generated controllers just below and well above them.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.control.sampling import _Z_ONLY, MARGIN, limits, sample_limit
from derive.errors import DeriveError
from derive.sim.backends import Backend
from derive.sim.simulate import Plant, run, true_plant

SMALL_ARM = Path(__file__).resolve().parent / "data" / "f6_small_arm.toml"


def _small_arm() -> derive.Arm:
    return derive.load_arm(SMALL_ARM)


def test_default_arm_dobc_and_npid_limits_lie_between_10_and_20_ms(paper):
    lim = limits(paper)
    for form in ("dobc", "npid"):
        assert 10e-3 < lim[form].limit < lim[form].raw < 20e-3, (form, lim[form])
        assert lim[form].limit == pytest.approx(MARGIN * lim[form].raw)
    assert lim["mpc"].limit > 0.1     # the predictive law alone tolerates far slower sampling


def test_one_link_arm_of_0_1_m_gets_a_limit_near_0_33_ms():
    d = derive.derive(_small_arm())
    for form in ("dobc", "npid"):
        lim = sample_limit(d, form)
        assert lim.raw == pytest.approx(2 * float(d.J[0, 0]) / float(d.W[0, 0]), rel=0.02)   # 2 J / w: 0.333 ms
        assert 0.30e-3 < lim.raw < 0.36e-3


def test_backward_euler_of_z_alone_leaves_the_limit_but_the_implicit_estimate_lifts_it(paper):
    """Backward Euler on z with the measurement taken before the step does not move the limit: in the
    sampled loop z + W theta' = B dhat telescopes, and the fast mode is the held velocity feedback
    B^-1 W theta' of u. The generated implicit step (eq. 21 at the end of the step, theta'_k included)
    makes that feedback W (J + dt W)^-1 J theta' and lifts the limit to the predictive law's own."""
    exp, z_only = sample_limit(paper, "dobc", "explicit"), sample_limit(paper, "dobc", _Z_ONLY)
    assert z_only.raw == pytest.approx(exp.raw, rel=0.03)
    imp = limits(paper, "implicit")
    assert imp["dobc"].raw > 30 * exp.raw
    assert imp["dobc"].raw == pytest.approx(limits(paper)["mpc"].raw, rel=0.03)   # the law u* limits it now
    assert 20 * limits(paper)["npid"].raw < imp["npid"].raw < imp["dobc"].raw      # W_dt K2 e limits NPID


def test_implicit_limits_of_the_one_link_arm_are_the_predictive_laws_not_2_j_over_w():
    d = derive.derive(_small_arm())
    euler, imp = limits(d, "explicit"), limits(d, "implicit")
    assert euler["dobc"].raw < 0.4e-3 < 0.3 < imp["npid"].raw < imp["dobc"].raw
    assert imp["dobc"].raw == pytest.approx(euler["mpc"].raw, rel=0.05)


def test_sample_limit_rejects_an_unknown_discretisation(paper):
    with pytest.raises(ValueError, match="expected a form of .* and an observer of .*got 'dobc', 'trapezoid'"):
        sample_limit(paper, "dobc", "trapezoid")


@pytest.fixture(scope="module")
def loops():
    """(arm, derivation, generated Python controller) per arm, built once (the sample time is not baked in)."""
    made = {}

    def get(name: str):
        if name not in made:
            arm = derive.load_arm(None if name == "default" else SMALL_ARM)
            d = derive.derive(arm)
            made[name] = (arm, d, Backend(d, "python"))
        return made[name]

    yield get
    for _, _, backend in made.values():
        backend.close()


def _simulate(loop, form: str, dt: float, duration: float, substeps: int = 4) -> float:
    """Largest |e| over the last third of a run of ``form`` at sample time dt (inf if it blew up)."""
    arm, d, backend = loop
    settings = replace(arm.simulation, sample_time=dt, duration=duration, substeps=substeps)
    try:
        with np.errstate(all="ignore"):
            tr = run(d, backend, Plant(d, true_plant(d, settings)), settings, form)
    except (DeriveError, FloatingPointError, np.linalg.LinAlgError, OverflowError):
        return np.inf
    e = np.abs(tr.yd - tr.theta)[2 * len(tr.t) // 3:]
    return float(np.max(e)) if np.all(np.isfinite(e)) else np.inf


@pytest.mark.parametrize("form", ["dobc", "npid"])
def test_default_arm_tracks_just_below_the_limit_and_diverges_well_above_it(loops, form):
    loop = loops("default")
    lim = limits(loop[1])[form]
    assert _simulate(loop, form, 0.98 * lim.limit, 9.0) < 0.05
    assert _simulate(loop, form, 2.0 * lim.raw, 3.0) > 1.0


@pytest.mark.parametrize("form", ["dobc", "npid"])
def test_one_link_arm_tracks_just_below_the_limit_and_diverges_well_above_it(loops, form):
    loop = loops("small")
    lim = sample_limit(loop[1], form)
    assert _simulate(loop, form, 0.98 * lim.limit, 1.5, substeps=1) < 0.05
    assert _simulate(loop, form, 2.0 * lim.raw, 0.2, substeps=1) > 1.0


def test_simulate_refuses_a_sample_time_above_the_limit_unless_forced(tmp_path, capsys):
    args = ["simulate", str(SMALL_ARM), "--controllers", "npid", "--duration", "0.004", "--out", str(tmp_path / "s")]
    assert main(args) == 2
    err = " ".join(capsys.readouterr().err.split())
    d = derive.derive(_small_arm())
    exp, imp = limits(d)["npid"], limits(d, "implicit")["npid"]
    assert (f"simulation.sample_time of f6_small_arm: sample_time = 2 ms is above the NPID limit "
            f"{exp.limit * 1e3:.3g} ms (the sampled loop is unstable from {exp.raw * 1e3:.3g} ms") in err
    assert 0.29e-3 < exp.limit < 0.31e-3 and imp.limit > 0.1   # 2 J / w explicit; the predictive law's, implicit
    # the refusal names --observer implicit and the limit of each refused form with it
    assert f"with --observer implicit the NPID limit is {imp.limit * 1e3:.3g} ms, which allows it" in err
    assert "use --observer implicit where it allows the sample time, or pass --force" in err
    assert not (tmp_path / "s").exists()
    assert main(args + ["--force"]) == 0          # two samples: not yet diverged
    assert main(["simulate", str(SMALL_ARM), "--controllers", "mpc", "--duration", "0.004",
                 "--out", str(tmp_path / "m")]) == 0   # the predictive law alone is within its limit


def test_generate_warns_and_show_prints_the_limits(tmp_path, capsys):
    assert main(["generate", str(SMALL_ARM), "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "warning: simulation.sample_time of f6_small_arm: sample_time = 2 ms is above the DOBC limit" in err
    assert main(["show"]) == 0
    text = capsys.readouterr().out
    assert max(map(len, text[text.index("Sample time:"):].splitlines())) <= 100
    out = " ".join(text.split())   # the sample-time paragraph is wrapped to 100 columns
    assert "Sample time: largest sample time" in out and "DOBC 11." in out and "NPID 11." in out
    imp = limits(derive.derive(derive.load_arm()), "implicit")
    assert f"DOBC {imp['dobc'].limit * 1e3:.3g} ms, NPID {imp['npid'].limit * 1e3:.3g} ms with --observer implicit" in out
