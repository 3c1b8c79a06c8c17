"""Write tests/data/old_planar_reference.json: values of the planar pipeline as
derived by the old planar CRBA/RNEA path (``derive.dynamics.planar.derive_dynamics``
at commit 5ab25ac, the last main before the chain dynamics), kept so that
tests/test_old_planar_reference.py can show the chain dynamics give the same
J, G, gravity, gains and control laws (1e-12) without the old code.

Run once, from a checkout of that commit: ``PYTHONPATH=<checkout> python
tests/data/old_planar_reference.py OUT.json MODULE.py`` (MODULE.py: the
generated Python module of glasgow_2link that commit's ``derive generate``
wrote; its kernels' outputs at :data:`POINTS` inputs are stored too). The symbols' values at each
point are stored beside the results (a point is a function of the symbol's
name and the point's index only, so both sides agree on it).
"""
from __future__ import annotations

import json
import sys
import zlib

import numpy as np
import sympy as sp

import derive
from derive.model.examples import planar_chain
from derive.model.spec import load_arm, packaged_arms

MATRICES = ("J", "G", "B", "K1", "K2", "W", "L", "P", "D", "I", "N", "dhat0", "u_star", "u_dobc", "u_npid", "dhat")
POINTS = 3


def value(name: str, k: int) -> float:
    return float(np.random.default_rng([zlib.crc32(name.encode()), k]).uniform(-1.5, 1.5))


def arms():
    for name in packaged_arms():
        yield name, load_arm(name)
    yield "chain4_gravity", planar_chain(4, gravity=9.81)


def evaluate(m: sp.Matrix, point: dict) -> list:
    from derive.dynamics.dag import Substitution
    put = Substitution({s: sp.Float(v, 40) for s, v in point.items()})
    m = put(m)
    m = sp.Matrix(m.doit() if isinstance(m, sp.MatrixExpr) else m)
    return [[float(sp.N(x, 30)) for x in row] for row in m.tolist()]


def load_module(path: str):
    import importlib.util

    spec = importlib.util.spec_from_file_location("generated_module", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def kernel_inputs(module, name: str, k: int) -> list:
    """Inputs of the kernel ``name`` of the generated module: a list per argument
    (dt = 1 ms), from the argument's name and the point index."""
    import inspect

    args = []
    for arg in inspect.signature(getattr(module, name)).parameters:
        if arg == "dt":
            args.append([0.001])
        else:
            args.append([value(f"{name}.{arg}[{i}]", k) for i in range(module.N)])
    return args


def kernels(module, names=None) -> dict:
    """The outputs of the module's kernels (``names``: those, default every one) at the points."""
    names = [n for n in sorted(dir(module)) if n.startswith("_kernel_")] if names is None else names
    return {name: [list(map(float, _flat(getattr(module, name)(*kernel_inputs(module, name, k)))))
                   for k in range(POINTS)] for name in names}


def _flat(x) -> list:
    if isinstance(x, (list, tuple)):
        return [y for item in x for y in _flat(item)]
    return [x]


def main(out: str, module_path: str) -> None:
    result = {"generated_glasgow_2link": kernels(load_module(module_path))}
    for name, arm in arms():
        d = derive.derive(arm)
        mats = {k: getattr(d, k) for k in MATRICES}
        mats["gravity"] = d.numeric(d.dynamics.gravity)
        syms = sorted(set().union(*(m.free_symbols for m in mats.values())), key=lambda s: s.name)
        entry = []
        for k in range(POINTS):
            point = {s: value(s.name, k) for s in syms}
            entry.append({"point": {s.name: v for s, v in point.items()},
                          "values": {key: evaluate(m, point) for key, m in mats.items()}})
        result[name] = entry
    with open(out, "w") as f:
        json.dump(result, f, allow_nan=False, indent=1, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
