"""The URDF corpus (tests/data/urdf/corpus/corpus.toml) as data: the arms, their arm-file
mappings and the Pinocchio model of each with the same held joints (shared by
tests/test_corpus.py and benchmarks/corpus.py)."""
from __future__ import annotations

import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

CORPUS = Path(__file__).parent / "data" / "urdf" / "corpus"
MJCF_CORPUS = Path(__file__).parent / "data" / "mjcf" / "menagerie"
INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


@dataclass(frozen=True)
class CorpusArm:
    """One entry of corpus.toml (its header comment says what each key means)."""

    name: str
    file: str
    base: str
    tip: str
    expect: str
    pipeline: str
    refusal: str = ""
    init_options: tuple[str, ...] = ()
    locked: dict = field(default_factory=dict, hash=False, compare=False)
    slow_load: bool = False
    kind: str = "urdf"    # "urdf" or "mjcf" (tests/data/mjcf/menagerie/corpus.toml)

    @property
    def urdf(self) -> Path:
        """The arm's file (a URDF, or an MJCF for kind "mjcf")."""
        return (MJCF_CORPUS if self.kind == "mjcf" else CORPUS) / self.file

    @property
    def repair(self) -> bool:
        return "--repair-inertia" in self.init_options


def corpus_arms(kind: str = "urdf") -> list[CorpusArm]:
    """Every arm of the URDF corpus.toml (``kind`` "urdf") or of the MJCF one ("mjcf"), in file order."""
    folder = MJCF_CORPUS if kind == "mjcf" else CORPUS
    data = tomllib.loads((folder / "corpus.toml").read_text(encoding="utf-8"))
    return [CorpusArm(**{**a, "init_options": tuple(a.get("init_options", ()))}, kind=kind) for a in data["arm"]]


def arm_mapping(arm: CorpusArm, n: int | None = None) -> dict:
    """The arm-file mapping of ``arm`` (torque actuation, gravity 9.81 along -z of the
    base, the controller settings of derive init), for derive.model.spec.arm_from_dict."""
    table = {"name": "corpus", "urdf": str(arm.urdf), "base_link": arm.base, "tip_link": arm.tip,
             "gravity": 9.81, "gravity_direction": [0, 0, -1], "actuation": "torque"}
    if arm.locked:
        table["locked"] = dict(arm.locked)
    if arm.repair:
        table["repair_inertia"] = True
    return {"arm": table, "controller": {"T1": 0.0, "T2": 0.2, "w": [5.0] * (n or 1)}}


def held_values(arm: CorpusArm, moving: list[str]) -> dict[str, float]:
    """Every moving joint of the URDF not in ``moving``, at its URDF value: locked's, a
    mimic's multiplier * master + offset (followed through mimics of mimics), else 0.
    Read from the XML directly, independently of derive's reader."""
    root = ET.parse(arm.urdf).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}

    def value(name: str, depth: int = 0) -> float:
        if name in arm.locked:
            return float(arm.locked[name])
        mimic = joints[name].find("mimic")
        if mimic is None or depth > len(joints):
            return 0.0
        return (float(mimic.get("multiplier", 1.0)) * value(mimic.get("joint"), depth + 1)
                + float(mimic.get("offset", 0.0)))
    return {name: value(name) for name, j in joints.items()
            if j.get("type") in ("revolute", "continuous", "prismatic") and name not in moving}


def urdf_with_inertias(arm: CorpusArm, tensors: dict[str, tuple], folder: Path) -> Path:
    """A copy of the arm's URDF in ``folder`` with the <inertia> of the links in
    ``tensors`` (link -> six entries) replaced: what a repaired file would say."""
    tree = ET.parse(arm.urdf)
    for link in tree.getroot().findall("link"):
        if link.get("name") in tensors:
            node = link.find("inertial/inertia")
            for key, x in zip(INERTIA_KEYS, tensors[link.get("name")]):
                node.set(key, repr(float(x)))
    path = folder / arm.file
    tree.write(path)
    return path


def dynamics_function(loaded):
    """J, the bias and g of ``loaded``'s dynamics (derive.model.spec.Arm) as one numeric function of
    (q, v): evaluate(q, v) -> (J (n x n), bias (n), g (n)) at the arm's parameter values."""
    import numpy as np

    from derive.dynamics.equations import derive_dynamics
    from derive.dynamics.program import lambdify

    d = derive_dynamics(loaded)
    n = d.n
    symbols = [s for s, _ in d.values]
    values = [float(v) for _, v in d.values]
    f = lambdify([*d.sym.theta, *d.sym.dtheta, *symbols], list(d.J) + list(d.bias) + list(d.gravity))

    def evaluate(q, v):
        out = np.array(f(*q, *v, *values), dtype=float)
        return out[:n * n].reshape(n, n), out[n * n:n * n + n], out[n * n + n:]
    return evaluate


def random_states(loaded, seed: int, count: int) -> list:
    """``count`` seeded states (q within each joint's limits, else +-pi or +-0.1 m; v in +-2) of ``loaded``."""
    import math

    import numpy as np

    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        q = []
        for j in loaded.chain.joints:
            lo, hi = j.limits.lower, j.limits.upper
            if j.type.value == "continuous" or lo is None or hi is None or hi <= lo:
                lo, hi = (-math.pi, math.pi) if j.type.rotates else (-0.1, 0.1)
            q.append(rng.uniform(float(lo), float(hi)))
        out.append((np.array(q), rng.uniform(-2.0, 2.0, len(q))))
    return out
