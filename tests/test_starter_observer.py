"""Issue 34 item 1: the starter file's observer step and sample time (derive.control.starter.choose_observer),
the arm file's controller.observer that the commands build by default, and ``derive tune``'s exit code
agreeing with what it prints."""
from __future__ import annotations

import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.control.certificate import Decision, Verdict
from derive.control.starter import USABLE, StarterGain, choose_observer
from derive.errors import SpecError

DATA = Path(__file__).parent / "data"
JACO = DATA / "urdf" / "corpus" / "j2s7s300_standalone.urdf"


def _gain(rate_max: float) -> StarterGain:
    dec = Decision(Verdict.PROVED, 1, 0.1, None, 0.1, 0.0)
    return StarterGain(W=((1.0,),), omega=1.0, rates=(1.0, rate_max), decision=dec, sample_time=2e-3,
                       observer_limit=1.8 / rate_max, momentum_limit=0.036, seconds=0.0)


def _stated(explicit_dobc: float, implicit_dobc: float) -> dict:
    lim = lambda x: SimpleNamespace(limit=x)   # noqa: E731: derive.control.sampling.SampleLimit's field
    return {"explicit": {"mpc": lim(0.0128), "dobc": lim(explicit_dobc), "npid": lim(explicit_dobc), "mom": lim(0.0098)},
            "implicit": {"mpc": lim(0.0128), "dobc": lim(implicit_dobc), "npid": lim(0.0357), "mom": lim(0.0098)}}


def test_choose_observer_takes_the_backward_euler_step_of_eq_21_when_forward_euler_needs_below_0_1_ms():
    """The Jaco 2's limits (forward Euler of eq. 21: DOBC and NPID 0.0239 ms; backward Euler: DOBC 6.48 ms): the
    starter takes the implicit step at 2 ms (half of 6.48 ms is 3.24, capped at 2 ms) and keeps the forward-Euler
    figure (10 us) for the file to state; limits that allow 0.1 ms forward-Euler keep the explicit step."""
    g = choose_observer(_gain(7.5e4), _stated(2.39e-5, 6.48e-3))
    assert (g.observer, g.sample_time, g.explicit_time) == ("implicit", 2e-3, 1e-5)
    kept = choose_observer(_gain(1e3), _stated(7.19e-4, 6.48e-3))
    assert (kept.observer, kept.explicit_time) == ("explicit", None) and kept.sample_time >= USABLE
    stuck = choose_observer(_gain(7.5e4), _stated(2.39e-5, 2.0e-5))   # the implicit step no better: explicit kept
    assert stuck.observer == "explicit" and stuck.sample_time < USABLE


def _arm_text(observer: str) -> str:
    text = (DATA / "urdf" / "double_pendulum.toml").read_text(encoding="utf-8")
    return text.replace("[controller]\n", f"[controller]\nobserver = {observer}\n", 1)


def test_controller_observer_is_read_and_a_bad_value_is_named(tmp_path):
    shutil.copy(DATA / "urdf" / "double_pendulum.urdf", tmp_path)
    path = tmp_path / "a.toml"
    path.write_text(_arm_text('"implicit"'), encoding="utf-8")
    assert derive.load_arm(path).controller.observer == "implicit"
    path.write_text(_arm_text('"backward"'), encoding="utf-8")
    with pytest.raises(SpecError, match=r"controller\.observer.*'explicit' or 'implicit'.*backward"):
        derive.load_arm(path)


@pytest.mark.slow
def test_jaco_starter_runs_at_a_usable_sample_time_with_the_implicit_step(tmp_path, capsys):
    """Issue 34 item 1, the handed case: the Jaco 2's forward-Euler step would need 10 us (W J^-1's rates spread
    3100-fold); the starter writes observer = "implicit" and 2 ms, says why with both steps' DOBC/NPID limits, and
    its certificate comment states derive check's own decision (proved: the same W, box and cell budget); derive
    simulate builds the implicit step without --observer and does not refuse the sample time (measured: the 120 s
    experiment in 20 s CPU, 285 MiB, against 279 s and 7.6 GB at 10 us)."""
    from derive.control.certificate.report import inertia_model
    from derive.control.certificate import DEFAULT_BUDGET, ObserverCertificate

    urdf = tmp_path / "jaco.urdf"
    shutil.copy(JACO, urdf)
    assert main(["init", str(urdf), "--base", "j2s7s300_link_base", "--tip", "j2s7s300_end_effector"]) == 0
    path = tmp_path / "jaco.toml"
    text = path.read_text(encoding="utf-8")
    arm = derive.load_arm(path)
    assert arm.controller.observer == "implicit" and arm.simulation.sample_time >= 1e-3
    assert "would be 0.01 ms, below 0.1 ms" in text and "the implicit step's are DOBC" in text
    d = derive.derive(arm)
    shape = np.array([float(x) for x in arm.controller.max_joint_speed])
    W = np.array(d.W.tolist(), dtype=float)
    dec = ObserverCertificate(inertia_model(d), shape).decide(W, shape, 1.0, 0.0, DEFAULT_BUDGET)
    assert f"(its decision: {dec.verdict.value}, {dec.cells} cells" in text and dec.verdict is Verdict.PROVED
    capsys.readouterr()
    assert main(["simulate", str(path), "--duration", "0.2", "--controllers", "dobc", "--out", str(tmp_path / "s")]) == 0


@pytest.mark.parametrize("verdict, code", [(Verdict.PROVED, 0), (Verdict.UNPROVEN, 1)])
def test_tune_prints_a_line_to_paste_only_when_it_exits_0(monkeypatch, capsys, verdict, code):
    """Issue 34 item 1: derive tune exited 1 ("unproven") on the Jaco 2 yet printed a [controller] line to paste;
    the line now comes with exit 0 only, and an unproven W says there is nothing to paste."""
    import derive.control.certificate.synthesis as synthesis

    def fake(model, box, rate, structure):
        W = np.eye(len(box)) * 2.0
        return synthesis.Synthesis(W=W, structure=structure, box=tuple(box), rate=rate,
                                   decision=Decision(verdict, 7, None, None, 0.0, 0.0), headroom=0.3, samples=1,
                                   rounds=1, seconds=0.0, norm=2.0)

    monkeypatch.setattr(synthesis, "synthesise", fake)
    assert main(["tune", str(DATA / "urdf" / "double_pendulum.toml"), "--speed", "1,1"]) == code
    out = capsys.readouterr().out
    assert ("[controller] w = [2, 2]" in out) is (code == 0)
    assert ("no [controller] line to paste: this W is unproven" in out) is (code == 1)
