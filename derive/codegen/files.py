"""Emission: Derivation -> {relative path: text} for C and Python, plus MANIFEST.json.

Pure: renders everything to strings; ``derive.codegen.emit.write_tree`` writes.
"""
from __future__ import annotations

import hashlib
from collections.abc import Callable
from importlib import metadata

from derive import jsonio
from derive.codegen.kernels import ParamsMode
from derive.codegen.plant import plant_c_files, plant_view
from derive.codegen.regressor import base_parameter_manifest, regressor_files
from derive.control.pipeline import Derivation
from derive.codegen.render import render
from derive.codegen.views import ArmView, arm_view, kernel_functions, selftest_view
from derive.identify.regressor import derive_regressor

REALS = ("double", "float")
PINNED = ("sympy", "casadi", "numpy", "jinja2", "python-flint")  # output depends on their versions (constraints.txt)


def library_files(d: Derivation, real: str, mode: ParamsMode, v: ArmView | None = None) -> dict[str, str]:
    """The C library alone (API, glue, kernels), under ``c/``: what an embedding
    such as an FMU compiles (``v``: the arm's view when already built)."""
    v = arm_view(d, real, mode) if v is None else v
    a = d.arm.name
    return {
        f"c/{a}.h": render("c/arm.h.jinja", v=v),
        f"c/{a}.c": render("c/arm.c.jinja", v=v),
        f"c/{a}_kernels.h": render("c/kernels.h.jinja", v=v),
        f"c/{a}_kernels.c": render("c/kernels.c.jinja", v=v),
    }


def c_files(d: Derivation, real: str, mode: ParamsMode, notes: list[str] | None = None,
            v: ArmView | None = None, regressor: bool = False) -> dict[str, str]:
    """The C library, its self-test and CMakeLists.txt, under ``c/``; sentences
    for the user (a real type too coarse for the arm) are appended to ``notes``;
    ``regressor``: CMakeLists.txt builds <arm>_regressor.c too (derive.codegen.regressor)."""
    v = arm_view(d, real, mode) if v is None else v
    t = selftest_view(d, v)
    if notes is not None:
        notes.extend(t.warnings)
    a = d.arm.name
    return {
        **library_files(d, real, mode, v),
        f"c/{a}_selftest.c": render("c/selftest.c.jinja", v=v, t=t),
        "c/CMakeLists.txt": render("c/CMakeLists.txt.jinja", v=v, version=metadata.version("derive"),
                                   regressor=regressor),
        **plant_c_files(d, v, mode),
    }


def python_files(d: Derivation, mode: ParamsMode, v: ArmView | None = None) -> dict[str, str]:
    """The numpy-only Python module, under ``python/`` (always double precision;
    ``v``: the arm's double view when already built)."""
    v = arm_view(d, "double", mode) if v is None else v
    return {f"python/{d.arm.name}.py": render("python/arm.py.jinja", v=v, pl=plant_view(d, "double", mode))}


def observer_manifest(d: Derivation) -> dict:
    """W [N m s/rad] and its structure; for w = "auto" also the box, rate and certificate it was synthesised for."""
    out = {"W": [[str(x) for x in d.W.row(i)] for i in range(d.n)], "structure": d.observer.structure,
           "source": "synthesised" if d.synthesis is not None else "stated"}
    syn = d.synthesis
    if syn is not None:
        out.update({"box_rad_per_s": list(syn.box), "rate_per_s": syn.rate, "norm": syn.norm,
                    "headroom": syn.headroom, "certificate": {"verdict": syn.decision.verdict.value,
                                                              "cells": syn.decision.cells}})
    return out


GENERATE_STAGES = ("kernels", "C and self-test vectors", "Python")


def generate_files(d: Derivation, arm_bytes: bytes | None = None, real: str = "double",
                   mode: ParamsMode = ParamsMode.BAKED, notes: list[str] | None = None,
                   sample_time: str | None = None, stage: Callable[[str], None] | None = None,
                   observer: str = "explicit", regressor: bool = False) -> dict[str, str]:
    """Every generated file of one arm, with a manifest (no timestamps, no paths).

    The manifest's arm hash is of ``arm_bytes`` when given, else the hash
    load_arm took of the very bytes it validated. Warnings about the
    accuracy the real type can give are appended to ``notes``. ``sample_time``: the
    sentence of derive.control.sampling.limit_text.summary, stated in the headers (derive generate passes it).
    ``stage(name)``, when given, is called as each of GENERATE_STAGES begins (a progress bar).
    ``observer``: the observer step (derive.codegen.kernels.OBSERVER_STEPS); the manifest's
    options name it when it is not the default. ``regressor``: also the identification regressor
    (derive.codegen.regressor; ``derive generate --regressor``), its base parameters in the manifest."""
    stage = stage or (lambda name: None)
    stage("kernels")
    functions = kernel_functions(d, mode, observer)  # each kernel built once, printed for C and Python
    v = arm_view(d, real, mode, functions, sample_time, observer)
    py = v if real == "double" else arm_view(d, "double", mode, functions, sample_time, observer)
    stage("C and self-test vectors")
    c = c_files(d, real, mode, notes, v, regressor)
    stage("Python")
    files = {**c, **python_files(d, mode, py)}
    options: dict[str, object] = {"real": real, "params": mode.value}
    if observer != "explicit":
        options["observer"] = observer
    extra = {}
    if regressor:
        reg = derive_regressor(d.dynamics.chain)
        files.update(regressor_files(d, v, reg))
        options["regressor"] = True
        extra["base_parameters"] = base_parameter_manifest(reg)
    files["MANIFEST.json"] = manifest_text(d, files, arm_bytes, options, extra=extra)
    return files


def manifest_text(d: Derivation, files: dict[str, str | bytes], arm_bytes: bytes | None,
                  options: dict[str, object], command: str = "derive generate", extra: dict | None = None) -> str:
    """MANIFEST.json of generated ``files``: the arm file's name and sha256 (of
    ``arm_bytes`` when given, else of the bytes load_arm validated), the options,
    the pinned tool versions and each file's sha256; no timestamps, no paths. ``extra``:
    more entries, before ``files`` (the regressor's base parameters)."""
    manifest = {
        "_note": f"generated by derive; do not edit (regenerate with: {command})",
        "arm": d.arm.name,
        "arm_file": d.arm.source.replace("\\", "/").rsplit("/", 1)[-1],
        "arm_sha256": hashlib.sha256(arm_bytes).hexdigest() if arm_bytes is not None else d.arm.source_sha256,
        "options": options,
        "observer": observer_manifest(d),
        "versions": {"derive": metadata.version("derive"),
                     **{name: metadata.version(name) for name in PINNED}},
        **(extra or {}),
        "files": {path: hashlib.sha256(text.encode() if isinstance(text, str) else text).hexdigest()
                  for path, text in sorted(files.items())},
    }
    return jsonio.dumps(manifest)
