"""The error contract when a non-finite input is a compile-time constant the optimiser sees.

With link-time optimisation the caller's constant NaN or Inf reaches the kernels' arithmetic.
Under -ffast-math, -ffinite-math-only, -fno-honor-nans/-infinities clang marks that arithmetic
nnan/ninf, and an operation so marked with a NaN (Inf) operand is poison (LLVM LangRef, fast-math
flags): the result check after the kernel (the exponent bits of a poison value) may then be
folded either way. Only a check of the input's own bits, before any such arithmetic, is sure:
tests/fuzz/constant_nonfinite.c writes each case out with its constant.
"""
from __future__ import annotations

import pytest

import derive
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.kernels import ParamsMode

from .test_finite_math import ARM, ROOT, build, run

CASES = ROOT / "tests" / "fuzz" / "constant_nonfinite.c"
FLAGS = [(cc, flags) for cc in ("gcc", "clang")
         for flags in ("-O2 -ffast-math -flto", "-O3 -ffast-math -flto", "-O2 -ffinite-math-only -flto")]


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    root = tmp_path_factory.mktemp("constant_nonfinite")
    write_tree(root, generate_files(derive.derive(derive.load_arm(ARM)), b"", "double", ParamsMode.BAKED))
    return root / "c"


@pytest.mark.parametrize("cc,flags", FLAGS, ids=[f"{c} {f}" for c, f in FLAGS])
def test_a_constant_nonfinite_input_gives_the_error_code_under_lto(tree, tmp_path, cc, flags):
    exe = build(cc, flags, tree, CASES, tmp_path / "cases")
    assert run(exe).strip().splitlines()[-1] == "11 cases, 0 failed"
