"""The arm file's rules on the FMU's tunable parameters (derive.model.rules, issue 34 item 10).

A parameter's own range (its symbol's domain: > 0 or >= 0) is checked when it is set: the set
call (fmi2SetReal, fmi3SetFloat64/32) refuses a value outside it with fmi2Error/fmi3Error and a
logged message, and keeps the value it had; ``modelDescription.xml`` states it as ``min="0"``.
A rule on several parameters (T1 < T2, a full W's diagonal and determinant, a body's pseudo-inertia)
cannot be decided at one set: the importer sets them one by one, at a communication point, where
FMI lets tunable parameters change, and their new values act from the next step on (FMI 2.0 and
3.0, the definition of ``variability = "tunable"``). So those are checked where the values come into
use: fmi2ExitInitializationMode / fmi3ExitInitializationMode and the next fmi2DoStep /
fmi3DoStep after a parameter was set; a rule that does not hold makes that call return the
error (logged, naming the rule and the values), with the state and outputs unchanged.

The values of the multi-parameter rules are one CasADi kernel (``rules``: p -> value, slack),
printed to C like the plant's kernels; the glue compares each with 0 as its relation says.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import sympy as sp

from derive.codegen.printing import print_function
from derive.dynamics.dag import Memo
from derive.dynamics.sx import to_sx
from derive.fmu.plant import PlantKernel
from derive.model.chain import Parameter
from derive.model.rules import Rule, all_rules

UNIT_ROUNDOFF = {"double": "0x1p-53", "float": "0x1p-24"}   # C99 hexadecimal literals of 2^-53, 2^-24


@dataclass(frozen=True)
class Check:
    """One multi-parameter rule in the glue: the C condition that holds when the rule does (on
    ``value[k]``, ``slack[k]``), the rule in words, and a printf format and arguments of the
    values it reads (at most four shown)."""

    condition: str
    expected: str
    shown: str
    args: tuple[str, ...]


@dataclass(frozen=True)
class RulesView:
    """The multi-parameter rules of an FMU: the kernel, its inputs (C rvalues of the parameters,
    in order) and one :class:`Check` per rule; ``unit``: the real type's unit roundoff (C)."""

    kernel: PlantKernel
    inputs: tuple[str, ...]
    checks: tuple[Check, ...]
    unit: str


def fmu_rules(parameters: tuple[Parameter, ...], slots: dict[str, str], real: str, *,
              horizon_symbols: tuple[sp.Symbol, sp.Symbol] | None = None, W: sp.Matrix | None = None,
              bodies: tuple = ()) -> tuple[dict[str, tuple[str, str, str]], RulesView | None]:
    """The rules on ``parameters`` (derive.model.rules.all_rules) split for the FMU: those on one
    parameter (:func:`single_checks`, by name) and the kernel of the others (:func:`rules_view`);
    ``slots``: each parameter's C rvalue in the instance."""
    rules = all_rules(parameters, horizon_symbols=horizon_symbols, W=W, bodies=bodies)
    single = single_checks(rules)
    return single, rules_view([r for r in rules if not sp.sympify(r.value).is_Symbol], parameters, slots, real)


def single_checks(rules: tuple[Rule, ...]) -> dict[str, tuple[str, str, str]]:
    """Per parameter: (C condition on ``value``, XML min, the range in words) of the rules on it
    alone (its symbol's domain, a full W's diagonal entry > 0), which its setter checks."""
    out = {}
    for r in rules:
        value = sp.sympify(r.value)
        if value.is_Symbol and r.relation in (">", ">="):
            out[value.name] = (f"value {r.relation} 0", "0.0", f"{r.relation} 0")
    return out


def _condition(rule: Rule, k: int) -> str:
    if rule.relation == ">":
        return f"value[{k}] > 0"
    if rule.relation == "!=":
        return f"fabs(value[{k}]) > slack[{k}] * FMU_UNIT_ROUNDOFF"
    return f"value[{k}] >= 0" if rule.slack == 0 else f"value[{k}] >= -slack[{k}] * FMU_UNIT_ROUNDOFF"


def rule_function(rules: list[Rule], parameters: tuple[Parameter, ...]) -> tuple[ca.Function, tuple[sp.Symbol, ...]]:
    """The CasADi function p -> (value, slack) of ``rules`` (one entry each) and the parameter
    symbols p holds, in the order of ``parameters``."""
    order = [p.symbol for p in parameters]
    used = tuple(sorted({s for r in rules for s in sp.sympify(r.value).free_symbols | sp.sympify(r.slack).free_symbols},
                        key=order.index))
    p = ca.SX.sym("p", len(used))
    env = {s: p[i] for i, s in enumerate(used)}
    memo = Memo()
    value = ca.vertcat(*[to_sx(sp.sympify(r.value), env, memo) for r in rules])
    slack = ca.vertcat(*[to_sx(sp.sympify(r.slack), env, memo) for r in rules])
    return ca.Function("rules", [p], [value, slack], ["p"], ["value", "slack"], {"cse": True}), used


def rules_view(rules: list[Rule], parameters: tuple[Parameter, ...], slots: dict[str, str],
               real: str) -> RulesView | None:
    """The kernel and checks of ``rules`` (each on several of ``parameters``); None when there is none."""
    if not rules:
        return None
    fn, used = rule_function(rules, parameters)
    printed = print_function(fn, "c", "double")
    args = (f"const double p[{len(used)}]", f"double value[{len(rules)}]", f"double slack[{len(rules)}]")
    kernel = PlantKernel("rules", "the arm file's rules on several parameters (derive.model.rules)", args,
                         printed.registers, printed.statements, printed.operations, printed.unused_inputs)
    checks = []
    for k, r in enumerate(rules):
        names = r.names[:4]
        shown = ", ".join(f"{name} = %.15g" for name in names) + (", ..." if len(r.names) > 4 else "")
        checks.append(Check(_condition(r, k), r.expected, shown, tuple(f"(double){slots[name]}" for name in names)))
    return RulesView(kernel, tuple(slots[s.name] for s in used), tuple(checks), UNIT_ROUNDOFF[real])
