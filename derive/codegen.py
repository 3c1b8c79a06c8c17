"""Emission: Derivation -> {relative path: text} for C and Python, plus MANIFEST.json.

Pure: renders everything to strings; ``derive.emit.write_tree`` writes.
"""
from __future__ import annotations

import hashlib
import json
from importlib import metadata

from .kernels import ParamsMode
from .pipeline import Derivation
from .render import render
from .views import arm_view, selftest_view

REALS = ("double", "float")
PINNED = ("sympy", "casadi", "jinja2")  # exact versions in pyproject.toml: output depends on them


def c_files(d: Derivation, real: str, mode: ParamsMode) -> dict[str, str]:
    """The C library, its self-test and CMakeLists.txt, under ``c/``."""
    v = arm_view(d, real, mode)
    t = selftest_view(d, v)
    a = d.arm.name
    return {
        f"c/{a}.h": render("c/arm.h.jinja", v=v),
        f"c/{a}.c": render("c/arm.c.jinja", v=v),
        f"c/{a}_kernels.h": render("c/kernels.h.jinja", v=v),
        f"c/{a}_kernels.c": render("c/kernels.c.jinja", v=v),
        f"c/{a}_selftest.c": render("c/selftest.c.jinja", v=v, t=t),
        "c/CMakeLists.txt": render("c/CMakeLists.txt.jinja", v=v),
    }


def python_files(d: Derivation, mode: ParamsMode) -> dict[str, str]:
    """The numpy-only Python module, under ``python/`` (always double precision)."""
    return {f"python/{d.arm.name}.py": render("python/arm.py.jinja", v=arm_view(d, "double", mode))}


def generate_files(d: Derivation, arm_bytes: bytes, real: str = "double",
                   mode: ParamsMode = ParamsMode.BAKED) -> dict[str, str]:
    """Every generated file of one arm, with a manifest (no timestamps, no paths)."""
    files = {**c_files(d, real, mode), **python_files(d, mode)}
    manifest = {
        "generated_by": "derive; do not edit the files listed here",
        "arm": d.arm.name,
        "arm_file": d.arm.source.replace("\\", "/").rsplit("/", 1)[-1],
        "arm_sha256": hashlib.sha256(arm_bytes).hexdigest(),
        "options": {"real": real, "params": mode.value},
        "versions": {"derive": metadata.version("derive"),
                     **{name: metadata.version(name) for name in PINNED}},
        "files": {path: hashlib.sha256(text.encode()).hexdigest() for path, text in sorted(files.items())},
    }
    files["MANIFEST.json"] = json.dumps(manifest, indent=2, sort_keys=True) + "\n"
    return files
