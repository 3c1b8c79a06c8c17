"""Generated headers next to every standard header, in C and C++ (issue 10, item 4).

C99's <complex.h> defines the macro I, and the gains prototype named a parameter I: a
user's file that included <complex.h> first did not compile. Every identifier a
generated header declares is prefixed by the arm name or is a lowercase word of at
least two letters that no standard header defines (tests/test_headers.py checks the
headers' words against the macros the standard headers really define); the headers
compile after every C99 and C11 standard header with gcc and clang at -std=c99/-std=c11
-pedantic -Werror, and as C++17 (g++, clang++), where the self-test is built and run too.
"""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

import derive
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.kernels import ParamsMode

from .cbuild import STRICT

ARM = "glasgow_2link"
C99_HEADERS = ("assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal stdarg "
               "stdbool stddef stdint stdio stdlib string tgmath time wchar wctype").split()
C11_HEADERS = C99_HEADERS + "stdalign stdatomic stdnoreturn threads uchar".split()
# the <name.h> headers C++17 provides (D.5 [depr.c.headers]; no stdatomic, stdnoreturn, threads)
CPP_HEADERS = [h for h in C11_HEADERS if h not in ("stdatomic", "stdnoreturn", "threads")]
F4_CASE = """/* issue 10, item 4: a user's controller file that also does complex-number maths */
#include <complex.h>
#include "glasgow_2link.h"
int main(void)
{
    double P[4], D[4], Ig[4];
    const double th[2] = {0.1, 0.2};
    double complex s = 2.0 * I;
    glasgow_2link_gains(th, P, D, Ig);
    return (int)cimag(s) - 2;
}
"""


@pytest.fixture(scope="module")
def trees(tmp_path_factory) -> dict[tuple[str, str], Path]:
    d = derive.derive(derive.load_arm(ARM))
    root = tmp_path_factory.mktemp("headers")
    out = {}
    for real, mode in (("double", "baked"), ("float", "runtime")):
        write_tree(root / f"{real}_{mode}", generate_files(d, b"", real, ParamsMode(mode)))
        out[real, mode] = root / f"{real}_{mode}" / "c"
    return out


def _run(cmd: list[str], cwd: Path | None = None) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=cwd)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))}\n{proc.stdout}{proc.stderr}"
    return proc


def _objects(cc: str, c_dir: Path, out: Path) -> list[str]:
    """The library compiled as C."""
    objs = []
    for src in (f"{ARM}.c", f"{ARM}_kernels.c", f"{ARM}_plant.c"):
        obj = out / f"{cc}_{src}.o"
        _run([cc, *STRICT, "-O1", f"-I{c_dir}", "-c", str(c_dir / src), "-o", str(obj)])
        objs.append(str(obj))
    return objs


def _user_file(headers: list[str], runtime: bool) -> str:
    """Every standard header, then both generated ones, and calls through the public API."""
    p = f"&params, " if runtime else ""
    return "\n".join([*(f"#include <{h}.h>" for h in headers), f'#include "{ARM}.h"', f'#include "{ARM}_kernels.h"',
                      f'#include "{ARM}_plant.h"',
                      "#include <stdio.h>", "int main(void)", "{",
                      f"    {ARM}_input in = {{ {{0.1f, 0.2f}}, {{0, 0}}, {{0.5f, 0.5f}}, {{0, 0}}, {{0, 0}} }};",
                      f"    {ARM}_real u[2], gp[4], gd[4], gi[4], mass[4];",
                      f"    {ARM}_params params;" if runtime else "",
                      f"    {ARM}_params_default(&params);" if runtime else "",
                      f"    {ARM}_gains({p}in.theta, gp, gd, gi);",
                      f"    if ({ARM}_mpc_step({p}&in, u, NULL) != {ARM.upper()}_OK) return 1;",
                      f"    if ({ARM}_mass_matrix({p}in.theta, mass) != {ARM.upper()}_OK) return 1;",
                      '    printf("%.9g %.9g %.9g %.9g\\n", (double)u[0], (double)u[1], (double)gi[3], (double)mass[1]);',
                      "    return 0;", "}", ""])


@pytest.mark.parametrize("real,mode", [("double", "baked"), ("float", "runtime")])
@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_headers_compile_after_every_c99_and_c11_standard_header(trees, tmp_path, cc, real, mode):
    c_dir = trees[real, mode]
    objs = _objects(cc, c_dir, tmp_path)
    results = set()
    for std, headers in (("c99", C99_HEADERS), ("c11", C11_HEADERS)):
        src = tmp_path / f"user_{std}.c"
        src.write_text(_user_file(headers, mode == "runtime"))
        exe = tmp_path / f"user_{std}"
        flags = [f for f in STRICT if not f.startswith("-std=")]
        _run([cc, f"-std={std}", *flags, f"-I{c_dir}", str(src), *objs, "-lm", "-o", str(exe)]
             + (["-pthread"] if std == "c11" else []))
        results.add(_run([str(exe)]).stdout)
    assert len(results) == 1


@pytest.mark.parametrize("cxx,cc", [("g++", "gcc"), ("clang++", "clang")])
def test_headers_and_selftest_compile_as_cpp17_and_link_against_the_c_library(trees, tmp_path, cxx, cc):
    for (real, mode), c_dir in trees.items():
        objs = _objects(cc, c_dir, tmp_path)
        src = tmp_path / f"user_{real}.cpp"
        src.write_text(_user_file(CPP_HEADERS, mode == "runtime").replace("int main(void)", "int main()"))
        cpp_flags = ["-std=c++17", "-pedantic", "-Wall", "-Wextra", "-Werror", f"-I{c_dir}"]
        exe = tmp_path / f"user_{real}_cpp"
        _run([cxx, *cpp_flags, str(src), *objs, "-lm", "-o", str(exe)])
        c_exe = tmp_path / f"user_{real}_c"
        c_src = tmp_path / f"user_{real}.c"
        c_src.write_text(_user_file([], mode == "runtime"))
        _run([cc, *STRICT, f"-I{c_dir}", str(c_src), *objs, "-lm", "-o", str(c_exe)])
        assert _run([str(exe)]).stdout == _run([str(c_exe)]).stdout  # the same library, the same u
        selftest = tmp_path / f"selftest_{real}"
        _run([cxx, *cpp_flags, "-x", "c++", str(c_dir / f"{ARM}_selftest.c"), "-x", "none", *objs, "-lm",
              "-o", str(selftest)])
        assert re.search(r"^(\d+) passed, 0 failed$", _run([str(selftest)]).stdout, re.M)


def test_f4_complex_h_before_the_header_compiles_and_runs(trees, tmp_path):
    c_dir = trees["double", "baked"]
    src = tmp_path / "f4_complex_h.c"
    src.write_text(F4_CASE)
    objs = _objects("gcc", c_dir, tmp_path)
    exe = tmp_path / "f4"
    _run(["gcc", *STRICT, f"-I{c_dir}", str(src), *objs, "-lm", "-o", str(exe)])
    assert subprocess.run([str(exe)], timeout=60).returncode == 0


def _macros(cc: str, std: str, headers: list[str], tmp_path: Path, lang: str = "c") -> set[str]:
    """The names every standard header defines as macros (the preprocessor's own list)."""
    src = tmp_path / f"std_{cc}_{std}.{lang}"
    src.write_text("".join(f"#include <{h}.h>\n" for h in headers))
    out = _run([cc, f"-std={std}", "-dM", "-E", str(src)] + (["-pthread"] if lang == "c" else [])).stdout
    return {m.group(1) for m in re.finditer(r"^#define (\w+)", out, re.M)}


def test_no_word_of_a_generated_header_is_a_standard_macro_or_a_single_capital(trees, tmp_path):
    """The kind, beyond the headers tried: no identifier of a generated header (any
    parameter, member, type or macro) is a macro of a standard header, a C++ keyword
    used as a name, or a single capital letter (C's next <complex.h> may take it)."""
    macros = _macros("gcc", "c11", C11_HEADERS, tmp_path) | _macros("clang", "c11", C11_HEADERS, tmp_path)
    macros |= _macros("g++", "c++17", CPP_HEADERS, tmp_path, "cpp")
    for c_dir in trees.values():
        for header in (c_dir / f"{ARM}.h", c_dir / f"{ARM}_kernels.h", c_dir / f"{ARM}_plant.h"):
            code = re.sub(r"/\*.*?\*/", " ", header.read_text(), flags=re.S)
            code = re.sub(r'"[^"\n]*"', " ", code)  # extern "C"
            code = "\n".join(line for line in code.splitlines() if not line.lstrip().startswith("#"))
            words = set(re.findall(r"\b[A-Za-z_]\w*\b", code))
            own = {w for w in words if w.lower().startswith(ARM)}
            keywords = {"void", "int", "const", "typedef", "struct", "enum", "extern", "double", "float"}
            clashes = sorted((words - own - keywords) & macros)
            singles = sorted(w for w in words if len(w) == 1 and w.isupper())
            assert not clashes and not singles, (header.name, clashes, singles)
