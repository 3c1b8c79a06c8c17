"""Kernel specs, the SymPy-to-CasADi bridge and the printers: their guards."""
from __future__ import annotations

import casadi as ca
import pytest
import sympy as sp

import derive
from derive.codegen.casadi_bridge import to_function
from derive.errors import CoverageError, DerivationError
from derive.codegen.kernels import KernelSpec, ParamsMode, Port, kernel_specs
from derive.codegen.printing import c_literal, print_function

x, y, z = sp.symbols("x y z", real=True)


def test_coverage_names_the_symbols_no_port_provides():
    with pytest.raises(CoverageError, match=r"kernel k: outputs use symbols no input port provides: y, z"):
        KernelSpec("k", (Port("a", (x,), ""),), (Port("out", (x + y * z,), ""),), "")


def test_coverage_rejects_a_symbol_in_two_ports():
    with pytest.raises(CoverageError, match=r"symbol x is in input ports a and b"):
        KernelSpec("k", (Port("a", (x,), ""), Port("b", (x,), "")), (Port("out", (x,), ""),), "")


def test_every_kernel_of_every_mode_covers_its_outputs():
    d = derive.derive(derive.load_arm("planar_3link"))
    for mode in ParamsMode:
        names = [k.name for k in kernel_specs(d, mode)]
        assert names == ["gains", "mpc", "npid", "dobc", "dobc_factor", "observer", "dobc_init", "dhat", "mom", "mom_next", "mom_init"]


def test_bridge_refuses_a_function_it_cannot_translate():
    spec = KernelSpec("k", (Port("a", (x,), ""),), (Port("out", (sp.gamma(x),), ""),), "")
    with pytest.raises(DerivationError, match="cannot translate gamma"):
        to_function(spec)


def test_bridge_is_exact_to_the_last_bit_for_rationals():
    spec = KernelSpec("k", (Port("a", (x,), ""),), (Port("out", (sp.Rational(19, 50) * x,), ""),), "")
    assert float(to_function(spec)(1.0)) == 0.38


def test_printer_refuses_an_operation_without_a_template():
    a = ca.SX.sym("a")
    f = ca.Function("k", [a], [ca.atan2(a, a + 1)], ["a"], ["out"])
    with pytest.raises(DerivationError, match="has no printer"):
        print_function(f, "c")


def test_float_literals_are_single_precision_and_suffixed():
    assert c_literal(0.1, "float") == "0.1f"
    assert c_literal(2.0, "float") == "2.0f"
    assert c_literal(2.0, "double") == "2.0"
    assert float(c_literal(0.1, "double")) == 0.1
