"""The registry of controller forms: one entry per form of the generated API.

Every consumer that offers a choice of form (``derive fmu --form``, the FMU glue,
the simulators) reads this registry instead of a list of its own, so a form
added to the generated code (its kernels, its ``<arm>_<name>_init/_step`` and,
where it estimates the disturbance, ``<arm>_<name>_estimate``) becomes
available everywhere by one entry here.

The C API of a form ``f`` (prefix ``<arm>_``, parameters first in runtime builds):

* stateless (``state is None``): ``int f_step(const input *in, real u[N], mask *clipped)``;
* with state: ``int f_init(f_state *s, const input *in)`` (``f_init(f_state *s, const input *in,
  real dt)`` for a form whose init needs the sample time in ``--observer implicit`` builds:
  :func:`init_takes_dt`) and
  ``int f_step(f_state *s, const input *in, real dt, real u[N], mask *clipped)``;
  ``clipped`` (NULL allowed) receives which joints' u the voltage or torque limits clipped
  (the Python module's ``f_step`` returns ``(code, u, clipped)``);
* ``estimate``: ``int f_estimate(const f_state *s, const input *in, real dhat[N])``,
  the disturbance estimate the next step from ``s`` uses.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FormState:
    """The caller-owned state struct of a form: C type suffix, field, its meaning."""

    type: str    # "npid_state": the struct is <arm>_npid_state
    field: str   # "int_e": the struct's one array of N reals
    doc: str


@dataclass(frozen=True)
class Form:
    """One controller form of the generated API (see the module docstring)."""

    name: str
    title: str
    law: str          # the control law, plain ASCII
    equations: str    # the paper's equations, e.g. "eq. 34-38"
    state: FormState | None
    estimate: bool    # has <arm>_<name>_estimate (dhat, eq. 22)
    estimate_law: str = ""   # what that estimate is, plain ASCII (forms with an estimate)
    init_dt_implicit: bool = False   # f_init takes dt in --observer implicit builds (dhat(0) with W_dt)


FORMS: dict[str, Form] = {f.name: f for f in (
    Form("npid", "nonlinear PID predictive controller", "u = P e + D e' + I int e + N", "eq. 34-38",
         FormState("npid_state", "int_e", "integral of the tracking error e = yd - C theta [rad s]"),
         estimate=False),
    Form("dobc", "disturbance-observer-based controller", "u = u* - dhat, dhat = B^-1 (z + W theta')",
         "eq. 21-27", FormState("dobc_state", "z", "observer state z (eq. 21)"), estimate=True,
         estimate_law="dhat = B^-1 (z + W theta') (eq. 22)", init_dt_implicit=True),
    Form("mpc", "nonlinear predictive controller", "u = u* (no disturbance estimate)", "eq. 15",
         None, estimate=False),
    Form("mom", "generalized-momentum observer with the predictive law",
         "u = u* - dhat, dhat = B^-1 K (J theta' - m)", "eq. 15, 27; derive.control.momentum",
         FormState("mom_state", "m", "momentum observer state m: r = K (J theta' - m)"), estimate=True,
         estimate_law="dhat = B^-1 r, r = K (J theta' - m) (the generalized-momentum observer: r' = K (B d - r))"),
)}
DEFAULT_FORM = "npid"


def form(name: str) -> Form:
    """The registered form ``name``; KeyError for an unknown one (callers word the message)."""
    return FORMS[name]


def init_takes_dt(f: Form, observer: str) -> bool:
    """Whether ``<arm>_<f>_init`` takes the sample time in a build with the observer step
    ``observer`` (the implicit DOBC: its initial estimate uses W_dt = W (J + dt W)^-1 J)."""
    return f.init_dt_implicit and observer == "implicit"
