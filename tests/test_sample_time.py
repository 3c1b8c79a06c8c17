"""The largest sample time of the generated controllers (issue 12, item 4).

The limits come from the linearised sampled loop (derive.control.sampling); the tests hold them
against closed-loop simulations of the generated controllers just below and well above them.
"""
from __future__ import annotations

from dataclasses import replace
from fractions import Fraction
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import sympy as sp

import derive
from derive.cli import main
from derive.control.sampling.grid import configurations, spans
from derive.control.sampling.limit_text import summary, summary_all
from derive.control.sampling import _Z_ONLY, MARGIN, _loop, _radii, limits, operating_points, sample_limit
from derive.errors import DeriveError
from derive.sim.backends import Backend
from derive.sim.simulate import Plant, run, true_plant

from .sampled import growth, nominal_plant

SMALL_ARM = Path(__file__).resolve().parent / "data" / "f6_small_arm.toml"
URDF_DIR = Path(__file__).resolve().parent / "data" / "urdf"


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


# -- issue 20: the grid covers the stated box; the momentum observer's false "0 ms"; limits match the loop ----------
MY3 = Path(__file__).resolve().parent / "data" / "my3.toml"
PANDA = Path(__file__).resolve().parent / "data" / "urdf" / "panda.toml"


def _at_rest(path: Path) -> derive.Derivation:
    arm = derive.load_arm(path)
    return derive.derive(replace(arm, controller=replace(arm.controller, max_joint_speed=None)))


def test_my3_momentum_observer_limit_is_positive_on_its_speed_box_and_below_2_over_k():
    """my3 states max_joint_speed = [3, 4, 5]: in the momentum observer's own coordinates m the frozen-time
    linearisation at speed had a mode of rate 6.9 1/s at every dt ("MOM 0 ms"); in the residual's (x, r) the
    loop is stable as dt -> 0 and the limit lies below the observer's own 2 / K (40 ms at rest)."""
    d = derive.derive(derive.load_arm(MY3))
    for observer in ("explicit", "implicit"):
        lim = limits(d, observer)
        assert all(0 < lim[f].limit < lim[f].raw for f in lim), (observer, lim)
    mom = limits(d)["mom"]
    assert 0.02 < mom.raw < 2.0 / 50 and mom.worst[1] != (0.0, 0.0, 0.0)   # limited at speed
    assert "MOM 29" in summary_all(d) and "none (the linearised loop is unstable" not in summary_all(d)


@pytest.fixture(scope="module")
def my3_at_rest():
    d = _at_rest(MY3)
    made = {obs: Backend(d, "python", observer=obs) for obs in ("explicit", "implicit")}
    yield d, made
    for backend in made.values():
        backend.close()


@pytest.mark.parametrize("observer, form", [("explicit", f) for f in ("mpc", "dobc", "npid", "mom")]
                         + [("implicit", f) for f in ("dobc", "npid")])
def test_my3_limits_match_the_simulated_loop_at_their_worst_pose(my3_at_rest, observer, form):
    """At the pose that fails first, the generated controller on the arm's own plant (tests/sampled.py) holds a
    1e-6 rad offset at 0.95 x the raw limit (growth below 10 in 300 samples) and lets it grow past 100 x (or
    diverge) at 1.2 x within 600 samples (measured: at most 0.49 against at least 495; MPC's worst pose is
    upright since the fastest poses join the grid, where it grows 29x in 300 samples and 2,050x in 600): every form,
    both observer steps, on the 3-joint vertical arm (at rest: the poses are equilibria, the analysis exact)."""
    d, backends = my3_at_rest
    lim = limits(d, observer)[form]
    q0, dq0 = lim.worst
    plant = nominal_plant(d)
    below = growth(d, backends[observer], plant, form, 0.95 * lim.raw, q0, dq0, 300)
    above = growth(d, backends[observer], plant, form, 1.2 * lim.raw, q0, dq0, 600)
    assert below < 10 and above > 100


@pytest.mark.slow
@pytest.mark.parametrize("observer", ["explicit", "implicit"])
def test_panda_limits_match_the_simulated_loop_at_their_worst_pose(observer):
    """The same check on the 7-joint Panda (tests/data/urdf/panda.toml), every form."""
    d = _at_rest(PANDA)
    backend = Backend(d, "python", observer=observer)
    plant = nominal_plant(d)
    try:
        for form in ("mpc", "dobc", "npid", "mom") if observer == "explicit" else ("dobc", "npid"):
            lim = limits(d, observer)[form]
            q0, dq0 = lim.worst
            assert growth(d, backend, plant, form, 0.95 * lim.raw, q0, dq0, 300) < 10, form
            assert growth(d, backend, plant, form, 1.2 * lim.raw, q0, dq0, 300) > 100, form
    finally:
        backend.close()


def _spinning(speed: float) -> derive.Derivation:
    arm = derive.load_arm()
    box = (Fraction(speed), Fraction(speed))
    return derive.derive(replace(arm, controller=replace(arm.controller, max_joint_speed=box)))


def test_default_arm_with_a_60_rad_s_box_is_stable_at_its_stated_limit_with_joint_1_spinning():
    """Issue 20: at rest the default arm's explicit limit (11.7 ms) is unstable with joint 1 at 50-60 rad/s
    (rho 1.07-1.19); with max_joint_speed = [60, 60] the grid holds the box and the stated limits are stable at
    every grid point and on a finer set: joint 1 at 50, 55 and 60 rad/s, joint 2 at rest, 64 angles theta2."""
    d = _spinning(60.0)
    loop = _loop(d)
    grid = operating_points(d)
    spins = [(np.array([0.0, t2]), np.array([v, 0.0])) for v in (50.0, 55.0, 60.0)
             for t2 in np.linspace(-np.pi, np.pi, 64, endpoint=False)]
    assert any(abs(dq[0]) == 60 and dq[1] == 0 for _, dq in grid)     # joint 1 alone at its bound is a grid point
    for observer in ("explicit", "implicit"):
        for form, lim in limits(d, observer).items():
            for pts in (grid, spins):
                Q = np.array([q for q, _ in pts])
                DQ = np.array([dq for _, dq in pts])
                rho = _radii(loop, form, observer, lim.limit, loop.linearise(form, Q, DQ))
                assert rho.max() < 1.0, (observer, form, float(rho.max()))
    at_rest = limits(derive.derive(derive.load_arm()))["dobc"].limit
    bad = [(np.array([0.0, t2]), np.array([55.0, 0.0])) for t2 in np.linspace(-np.pi, np.pi, 16, endpoint=False)]
    rho = _radii(loop, "mpc", "explicit", at_rest, loop.linearise("mpc", *map(np.array, zip(*bad))))
    assert rho.max() > 1.05                                             # the independent check's finding


def test_default_arm_spinning_at_60_rad_s_tracks_in_simulation_at_the_stated_limits():
    """The generated controllers at the stated limits, joint 1 spinning at 60 rad/s (a relative equilibrium of the
    horizontal arm): a 1e-6 rad offset stays bounded over 200 samples, every form."""
    d = _spinning(60.0)
    backend = Backend(d, "python")
    try:
        for form, lim in limits(d).items():
            assert growth(d, backend, nominal_plant(d), form, lim.limit, (0.0, np.pi), (60.0, 0.0), 200) < 10, form
    finally:
        backend.close()


def test_statements_say_what_the_grid_covers():
    """At rest when no box is stated; the URDF's velocity limits when the arm file states none."""
    text = summary_all(derive.derive(derive.load_arm()))
    assert "64 configurations within the joint limits, speeds at rest only (no speed box" in text
    urdf = derive.derive(derive.load_arm(URDF_DIR / "round3" / "polar.toml"))
    assert "speeds at rest and up to the URDF's velocity limits [3, 1]" in summary(urdf)
    assert "speeds at rest and up to controller.max_joint_speed [3, 4, 5]" in summary(derive.derive(
        derive.load_arm(MY3)))


def test_operating_points_stay_within_the_joint_limits():
    """Kinova's ranges lie partly outside -pi..pi (joint 2 in [0.82, 5.46] rad); a prismatic joint's coordinate
    is metres within its travel (polar: [0.3, 0.6] m; synthetic: [0, 0.12] m), never -pi..pi."""
    for name, check in (("kinova.toml", lambda q: 0.82 <= q[1] <= 5.463),
                        ("round3/polar.toml", lambda q: 0.3 <= q[1] <= 0.6 and -3 <= q[0] <= 3),
                        ("synthetic.toml", lambda q: 0.0 <= q[3] <= 0.12)):
        qs = configurations(_joints_of(URDF_DIR / name))   # the grid reads the arm's joints only
        assert len(qs) > 1 and all(check(q) for q in qs), name
    assert {round(q[1], 9) for q in configurations(_joints_of(URDF_DIR / "round3" / "polar.toml"))} >= {0.3, 0.6}


def _joints_of(path: Path) -> SimpleNamespace:
    arm = derive.load_arm(path)
    return SimpleNamespace(arm=arm, n=arm.n, theta=tuple(sp.symbols(f"theta1:{arm.n + 1}")))


def test_a_zero_width_range_counts_as_none():
    """double_pendulum.urdf writes <limit lower="0" upper="0">: the grid ranges over a turn."""
    assert spans(_joints_of(URDF_DIR / "double_pendulum.toml")) == [(-np.pi, np.pi, True)] * 2


# -- a loop whose limit lies below DT_MIN (tester: round2 f1/f2, T2 = 1e-20) ------------------------------------------
F1 = """[arm]
name = "f1_float_inf"

[[link]]
length = 0.3
mass = 0.5

[[motor]]
torque_constant = 0.05
voltage_constant = 0.05
resistance = 2.0

[controller]
T1 = 0.0
T2 = 1e-20
w = [1.0]
"""


def test_a_stable_loop_too_fast_for_dt_min_has_a_limit_below_it_that_reads_in_every_sentence(tmp_path):
    """f1: T1 = 0, T2 = 1e-20 give K2 = 5 / (2 T2) (eq. 16), so the continuous MPC loop's poles have real part
    -K2 / 2 = -1.25e20 1/s (stable; derive check proves it Hurwitz), and every sampled form is unstable already
    at DT_MIN = 1e-7 s. Its limit is "below 1e-7 s", never "none (... unstable as dt -> 0 ...)", and the
    sentences embedding it read as sentences."""
    from derive.control.sampling.limit_text import too_slow
    from derive.control.sampling import DT_MIN, _continuous_rate

    path = tmp_path / "f1.toml"
    path.write_text(F1, encoding="utf-8")
    d = derive.derive(derive.load_arm(path))
    loop = _loop(d)
    pts = operating_points(d)
    L = loop.linearise("mpc", np.array([q for q, _ in pts]), np.array([dq for _, dq in pts]))
    assert np.allclose(_continuous_rate(loop, "mpc", L), -1.25e20, rtol=1e-6)
    for observer in ("explicit", "implicit"):
        lim = limits(d, observer)
        assert all(x.below and x.limit == 0 and x.raw == DT_MIN for x in lim.values()), lim
    for text in (summary(d), summary_all(d), *too_slow(d, 1e-3), *too_slow(d, 1e-3, observer="implicit")):
        assert "none" not in text and "unstable as dt -> 0" not in text, text
    assert "MPC below 1e-7 s, DOBC below 1e-7 s, NPID below 1e-7 s, MOM below 1e-7 s" in summary(d)
    dobc = next(t for t in too_slow(d, 1e-3) if "DOBC" in t)
    assert dobc == ("sample_time = 1 ms is above the DOBC limit, which is below 1e-7 s (the sampled loop is unstable "
                    "at 1e-7 s at some operating point, although the continuous loop is stable at every one: its "
                    "fastest mode needs a shorter sample time); with --observer implicit the DOBC limit is below "
                    "1e-7 s, which does not allow it either")


def test_the_continuous_loop_is_stable_on_an_arm_with_a_sampling_limit(paper):
    """The continuous rate is the dt -> 0 limit of the sampled loop: negative at every point (all forms, MOM
    in the residual's coordinates) where the sampled loop has a positive limit; a loop unstable as dt -> 0
    (limit 0, not below) is said to be so, not given a limit."""
    from derive.control.sampling.limit_text import _beyond
    from derive.control.sampling import SampleLimit, _continuous_rate

    loop, pts = _loop(paper), operating_points(paper)
    Q, DQ = np.array([q for q, _ in pts]), np.array([dq for _, dq in pts])
    for form in ("mpc", "dobc", "npid", "mom"):
        assert (_continuous_rate(loop, form, loop.linearise(form, Q, DQ)) < 0).all(), form
    unstable = SampleLimit("dobc", "explicit", 0.0, 0.0, 8, None)
    assert _beyond("DOBC", unstable, "") == (
        "is not a sampling question: the DOBC loop is unstable at every sample time (its linearisation is unstable "
        "as dt -> 0 at some operating point: not a sampling limit)")


def test_mpc_limit_at_speed_is_within_1_3x_of_the_true_limit_at_the_worst_steady_spin():
    """Issue 34 item 2 (eq. 15 sampled): with the [60, 60] box the worst steady motion is joint 1 spinning at
    60 rad/s with the arm folded (theta2 = -pi), a relative equilibrium where the frozen-time loop is the exact
    variational one: stable at the stated 1.05 ms, unstable at 1.3 x it (the true limit there is 1.26 ms).
    The audit's "stable to 5 ms" ran 200 samples from theta2 = 0.3: at 2 ms the folded spin grows 175-fold
    over 3000 samples and stays within 1 over 200, so a short run cannot see it."""
    d = _spinning(60.0)
    stated = limits(d)["mpc"].limit
    loop = _loop(d)
    Q, DQ = np.array([[0.0, -np.pi]]), np.array([[60.0, 0.0]])
    L = loop.linearise("mpc", Q, DQ)
    assert _radii(loop, "mpc", "explicit", stated, L).max() < 1.0
    assert _radii(loop, "mpc", "explicit", 1.3 * stated, L).max() > 1.0
    backend = Backend(d, "python")
    try:
        plant = nominal_plant(d)
        assert growth(d, backend, plant, "mpc", stated, Q[0], DQ[0], 3000) < 2.0
        assert growth(d, backend, plant, "mpc", 1.9 * stated, Q[0], DQ[0], 3000) > 10.0
    finally:
        backend.close()


def test_mom_limit_at_speed_is_conservative_by_at_least_10x_as_documented():
    """Issue 34 item 2, stated as open in docs/background/equations.md: MOM's stated 0.53 ms comes from the box's
    vertex where both joints spin (not a steady motion: theta2 turns 0.5 rad in a sample of 8 ms, which the
    frozen-time loop does not see). There, and at the worst steady spin, the generated loop tracks over 3000
    samples at 10 x the stated limit."""
    d = _spinning(60.0)
    lim = limits(d)["mom"]
    assert lim.worst is not None and all(abs(v) == 60.0 for v in lim.worst[1])   # a vertex: both joints spin
    backend = Backend(d, "python")
    try:
        plant = nominal_plant(d)
        for q0, dq0 in (lim.worst, ((0.0, -np.pi), (60.0, 0.0))):
            assert growth(d, backend, plant, "mom", 10.0 * lim.limit, q0, dq0, 3000) < 10.0, (q0, dq0)
    finally:
        backend.close()
