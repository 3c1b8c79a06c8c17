"""The chain dynamics give the packaged planar arms the same J, G, gravity,
gains and control laws as the old planar CRBA/RNEA path did (issue 11:
"the existing packaged arms derive exactly the same dynamics as before").

tests/data/old_planar_reference.json holds values computed by that old path
(tests/data/old_planar_reference.py, run at commit 5ab25ac before the path was
removed): every matrix of the Derivation at three points of all its symbols.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.model.examples import planar_chain
from derive.model.spec import load_arm

from .data.old_planar_reference import MATRICES, POINTS, evaluate, kernel_inputs, kernels, load_module, value

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = json.loads((ROOT / "tests" / "data" / "old_planar_reference.json").read_text())


def _arm(name: str):
    return planar_chain(4, gravity=9.81) if name == "chain4_gravity" else load_arm(name)


def compare(d, entry: dict) -> list[str]:
    """Names of the matrices of ``d`` that differ from the stored values by more than 1e-12 (relative to the largest entry)."""
    mats = {k: getattr(d, k) for k in MATRICES}
    mats["gravity"] = d.numeric(d.dynamics.gravity)
    bad = []
    for point in entry:
        at = {s: point["point"][s.name] for m in mats.values() for s in m.free_symbols}
        for key, m in mats.items():
            want = np.array(point["values"][key])
            got = np.array(evaluate(m, at))
            scale = max(1.0, float(np.abs(want).max()))
            if got.shape != want.shape or np.abs(got - want).max() > 1e-12 * scale:
                bad.append(key)
    return bad


@pytest.mark.parametrize("name", sorted(set(REFERENCE) - {"generated_glasgow_2link"}))
def test_eq12_chain_dynamics_equal_the_old_planar_path(name: str) -> None:
    d = derive.derive(_arm(name))
    assert compare(d, REFERENCE[name]) == []


def test_old_planar_comparison_fails_for_a_changed_arm() -> None:
    """The comparison can fail: a heavier second link is told apart in J, G, g and the laws."""
    arm = load_arm("vertical_2link")
    link = dataclasses.replace(arm.links[1], mass=arm.links[1].mass * 2)
    d = derive.derive(dataclasses.replace(arm, links=arm.links[:1] + (link,)))
    bad = compare(d, REFERENCE["vertical_2link"])
    assert {"J", "G", "gravity", "u_npid"} <= set(bad)


def test_generated_python_module_computes_what_the_old_one_did() -> None:
    """generated/glasgow_2link's Python module (regenerated through the chain
    dynamics: fewer operations, other expression order) computes every kernel
    as the module the old planar path generated did, to 1e-12."""
    module = load_module(str(ROOT / "generated" / "glasgow_2link" / "python" / "glasgow_2link.py"))
    # the generalized-momentum observer's kernels (issue 12 item 6) and dobc_factor came after the old path; the
    # DOBC's observer step takes the law's a and u and J's LDL^T factor since issue 23: checked below
    changed = {"_kernel_dobc", "_kernel_observer"}
    names = [n for n in dir(module) if n.startswith("_kernel_")]
    got = kernels(module, [n for n in names if n not in changed])
    want = REFERENCE["generated_glasgow_2link"]
    assert sorted(set(names) - set(want)) == ["_kernel_dobc_factor", "_kernel_mom", "_kernel_mom_init",
                                              "_kernel_mom_next"]
    assert set(want) <= set(names)
    n = module.N
    for k in range(POINTS):   # the old kernels' inputs, the new kernels composed as the glue does
        x = kernel_inputs(module, "_kernel_dobc", k)
        got.setdefault("_kernel_dobc", []).append(list(map(float, module._kernel_dobc(*x)[0])))
        theta, dtheta, z, u = ([value(f"_kernel_observer.{arg}[{i}]", k) for i in range(n)]
                               for arg in ("theta", "dtheta", "z", "u"))   # the old kernel's inputs
        dt = [0.001]
        # at yd = theta, yd' = theta', yd'' = 0 the law's a is 0: y = -J^-1 B (u - u_law) = J^-1 (G - B u - W theta' - z)
        law, a, trig = module._kernel_dobc(theta, dtheta, theta, dtheta, [0.0] * n, z)
        (ldl,) = (module._kernel_dobc_factor(theta, trig),)
        assert list(a) == [0.0] * n
        got.setdefault("_kernel_observer", []).append(list(map(float, module._kernel_observer(z, a, ldl, law, u, dt))))
    for name in want:
        for a, b in zip(got[name], want[name]):
            scale = max(1.0, max(abs(x) for x in b))
            assert np.abs(np.array(a) - np.array(b)).max() <= 1e-12 * scale, name
