"""The generated C as a CMake library a parent project uses (issue 15 item 5).

A tiny consumer (one ``main.c`` calling ``<arm>_mpc_step``, eq. 15, and printing u and the
clipped-joints mask) is configured and built with the machine's cmake in ``tmp_path`` two
ways: ``add_subdirectory(generated/<arm>/c)`` and ``find_package(<arm>)`` after
``cmake --install``. Its printed u equals the generated Python module's (1e-12); the
consumer's own compile lines carry no flag of ours; the library's default build type,
tests option and -Werror apply only when the generated project is built on its own.
"""
from __future__ import annotations

import importlib.util
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
ARM = "glasgow_2link"
SRC = ROOT / "generated" / ARM / "c"
X = (0.3, -0.2, 1.0, 0.5, 0.1, 0.2, 0.0, 0.3, 0.0, 0.0)   # theta, dtheta, yd, dyd, ddyd (2 joints)

MAIN_C = f"""#include <stdio.h>
#include "{ARM}.h"
#include "{ARM}_plant.h"

int main(void)
{{
    {ARM}_input in = {{ {{{X[0]}, {X[1]}}}, {{{X[2]}, {X[3]}}}, {{{X[4]}, {X[5]}}}, {{{X[6]}, {X[7]}}},
                        {{{X[8]}, {X[9]}}} }};
    {ARM}_real u[2], J[4];
    {ARM}_mask clipped = 99;
    if ({ARM}_mpc_step(&in, u, &clipped) != {ARM.upper()}_OK) return 1;
    if ({ARM}_mass_matrix(in.theta, J) != {ARM.upper()}_OK) return 1;
    printf("%.17g %.17g %lu %.17g\\n", (double)u[0], (double)u[1], (unsigned long)clipped, (double)J[0]);
    return 0;
}}
"""


def _consumer(folder: Path, find: str) -> Path:
    """A parent project whose only target links ``<arm>::<arm>``; ``find``: how it gets it."""
    folder.mkdir()
    (folder / "main.c").write_text(MAIN_C)
    (folder / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.13)\nproject(consumer C)\nenable_testing()\n"
        f"{find}\nadd_executable(consumer main.c)\n"
        f"target_link_libraries(consumer PRIVATE {ARM}::{ARM})\n")
    return folder


def _run(*cmd: str) -> str:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, " ".join(cmd) + "\n" + proc.stdout + proc.stderr
    return proc.stdout


def _build(src: Path, build: Path, *defs: str) -> dict[str, str]:
    """Configure (Makefiles, compile_commands.json) and build; the compile line of each source file."""
    _run("cmake", "-S", str(src), "-B", str(build), "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON", *defs)
    _run("cmake", "--build", str(build), "-j", "2")
    return {Path(c["file"]).name: c["command"] for c in json.loads((build / "compile_commands.json").read_text())}


def _cache(build: Path, name: str) -> str:
    for line in (build / "CMakeCache.txt").read_text().splitlines():
        if line.startswith(name + ":"):
            return line.split("=", 1)[1]
    return "<unset>"


@pytest.fixture(scope="module")
def expected() -> str:
    """u and the mask of eq. 15 at X from the generated Python module, J[0, 0] of the plant."""
    spec = importlib.util.spec_from_file_location(f"{ARM}_cmake", ROOT / "generated" / ARM / "python" / f"{ARM}.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    code, u, clipped = m.mpc_step(m.Input(X[0:2], X[2:4], X[4:6], X[6:8], X[8:10]))
    assert code == m.OK
    return np.array([*u, clipped, m.mass_matrix(np.array(X[0:2]))[1][0, 0]])


def _printed(exe: Path) -> np.ndarray:
    return np.array([float(w) for w in _run(str(exe)).split()])


def test_add_subdirectory_gives_a_namespaced_target_without_flags_tests_or_build_type(tmp_path, expected):
    parent = _consumer(tmp_path / "parent", f"add_subdirectory({SRC.as_posix()} {ARM})")
    build = tmp_path / "build"
    lines = _build(parent, build)
    assert np.allclose(_printed(build / "consumer"), expected, rtol=1e-12, atol=0)
    assert f"-I{SRC}" in lines["main.c"]                               # PUBLIC include directory
    for flag in ("-Werror", "-Wall", "-pedantic", "-std=", "-O"):      # nothing forced on the consumer
        assert flag not in lines["main.c"], (flag, lines["main.c"])
    assert "-Werror" not in lines[f"{ARM}.c"]                          # not even on the library here
    assert _cache(build, "CMAKE_BUILD_TYPE") == ""                     # the parent's choice stands
    assert "Total Tests: 0" in _run("ctest", "--test-dir", str(build), "-N")   # self-tests: opt-in
    assert not (build / ARM / f"{ARM}_selftest").exists()


def test_add_subdirectory_with_the_tests_option_registers_the_selftests_with_the_parents_ctest(tmp_path):
    parent = _consumer(tmp_path / "parent", f"add_subdirectory({SRC.as_posix()} {ARM})")
    build = tmp_path / "build"
    lines = _build(parent, build, f"-D{ARM.upper()}_BUILD_TESTS=ON")
    assert "-Werror" in lines[f"{ARM}_selftest.c"] and "-Werror" in lines[f"{ARM}.c"]   # the project's own tests
    assert "-Werror" not in lines["main.c"]
    out = _run("ctest", "--test-dir", str(build), "--output-on-failure")
    assert "100% tests passed, 0 tests failed out of 2" in out, out


def test_find_package_after_cmake_install_with_config_and_version_files(tmp_path, expected):
    build, prefix = tmp_path / "lib-build", tmp_path / "prefix"
    lines = _build(SRC, build, f"-DCMAKE_INSTALL_PREFIX={prefix}")    # the generated project on its own
    assert _cache(build, "CMAKE_BUILD_TYPE") == "Release"               # its default: optimised
    assert "-O3" in lines[f"{ARM}.c"] and "-Werror" in lines[f"{ARM}.c"]
    assert "100% tests passed" in _run("ctest", "--test-dir", str(build))
    _run("cmake", "--install", str(build))
    cmake_dir = prefix / "lib" / "cmake" / ARM
    assert {p.name for p in cmake_dir.glob(f"{ARM}Config*.cmake")} == {f"{ARM}Config.cmake", f"{ARM}ConfigVersion.cmake"}
    assert (prefix / "include" / ARM / f"{ARM}.h").is_file() and (prefix / "lib" / f"lib{ARM}.a").is_file()

    parent = _consumer(tmp_path / "parent", f"find_package({ARM} 0.1 CONFIG REQUIRED)")
    cbuild = tmp_path / "build"
    lines = _build(parent, cbuild, f"-DCMAKE_PREFIX_PATH={prefix}")
    assert np.allclose(_printed(cbuild / "consumer"), expected, rtol=1e-12, atol=0)
    assert str(prefix / "include" / ARM) in lines["main.c"]            # the installed include directory
    assert "-Werror" not in lines["main.c"] and "-Wall" not in lines["main.c"]

    wrong = _consumer(tmp_path / "wrong", f"find_package({ARM} 1.0 CONFIG REQUIRED)")   # the version file decides
    proc = subprocess.run(["cmake", "-S", str(wrong), "-B", str(tmp_path / "wrong-build"),
                           f"-DCMAKE_PREFIX_PATH={prefix}"], capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0 and "version: 0.1.0" in proc.stderr, proc.stderr
