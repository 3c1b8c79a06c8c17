"""derive identify --payload's result: mass, centre of mass and inertia with their standard
deviations, the arm file's ``[payload]`` table and the report.

From the estimate pi_p = (m, h, I_o) in F_n and its covariance (derive.identify.payload): the
centre of mass c = h / m, the inertia about it Ic = I_o - (|h|^2 1 - h h^T) / m (the parallel-axis
theorem), both turned into the tip link's frame (the inverse of derive.model.payload.tip_to_body:
c_tip = R^T (c - p), Ic_tip = R^T Ic R); the covariance carried through the Jacobian of that map
(central differences), so each figure has its standard deviation.

The inertia is written only when it is *identified consistently*: excited (derive.identify.payload),
a possible mass distribution (positive principal moments, each at most the sum of the other two,
as derive.model.payload checks the table) and determined (every entry's standard deviation at most
INERTIA_PRECISION of the largest principal moment). Otherwise mass and centre of mass only.

The ``[payload]`` table states a *range* (derive.model.payload): ``mass`` is the largest payload,
so the written mass is the larger of the file's and the identified one (the result says which);
``com`` the identified centre of mass; ``com_radius`` the larger of the file's and COM_SIGMAS
times the centre of mass's rms standard deviation sqrt(trace Cov(c)); ``inertia`` the identified
one scaled to the written mass (the table's inertia is at ``mass`` and scales with it). The text
is validated as an arm file before anyone writes it.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomlkit

from derive import jsonio
from derive.errors import DataError, DerivationError, SpecError
from derive.identify.armfile import relocate_urdf, urdf_target
from derive.identify.parameters import INERTIA_INDEX
from derive.identify.payload import PayloadFit
from derive.model.spec import Arm, arm_from_dict

INERTIA_PRECISION = 0.3   # an inertia entry's std at most this share of the largest principal moment
COM_SIGMAS = 3.0          # com_radius >= this many rms standard deviations of the centre of mass
MASS_SIGMAS = 3.0         # a mass within this many standard deviations of 0: no payload found
DIGITS = 6                # significant digits written


def _tip(arm: Arm) -> tuple[np.ndarray, np.ndarray]:
    tip = arm.chain.tip
    if tip is None:
        return np.eye(3), np.zeros(3)
    return np.array(tip.R.tolist(), dtype=float), np.array(tip.p.tolist(), dtype=float).reshape(3)


def _sym(six) -> np.ndarray:
    I = np.zeros((3, 3))
    for k, (a, b) in enumerate(INERTIA_INDEX):
        I[a, b] = I[b, a] = six[k]
    return I


def convert(pi: np.ndarray, R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(m, c_tip (3), Ic_tip (6, INERTIA_INDEX order)) of pi_p = (m, h, I_o) in F_n (module docstring)."""
    m, h = pi[0], pi[1:4]
    c = h / m
    Ic = R.T @ (_sym(pi[4:]) - ((h @ h) * np.eye(3) - np.outer(h, h)) / m) @ R
    return np.concatenate([[m], R.T @ (c - p), [Ic[a, b] for a, b in INERTIA_INDEX]])


@dataclass(frozen=True)
class PayloadResult:
    """The identified payload in the tip link's frame: mass [kg] and its std, com (3) [m], its std
    (3) and covariance (3 x 3), the inertia about the com (3 x 3) [kg m^2] and its std (3 x 3) (both
    None when not identified consistently), why not (``inertia_note``), the fit."""

    mass: float
    mass_std: float
    com: np.ndarray
    com_std: np.ndarray
    com_cov: np.ndarray
    inertia: np.ndarray | None
    inertia_std: np.ndarray | None
    inertia_note: str
    fit: PayloadFit

    @property
    def com_sigma(self) -> float:
        """sqrt(trace Cov(c)) [m]: the rms standard deviation of the centre of mass."""
        return float(np.sqrt(np.trace(self.com_cov)))


def payload_result(fit: PayloadFit, arm: Arm, where: str = "the logs") -> PayloadResult:
    """The result of ``fit`` (module docstring). DataError when the mass is within MASS_SIGMAS
    standard deviations of 0 (no payload the data can tell from none)."""
    R, p = _tip(arm)
    pi, cov = fit.pi, fit.cov
    m, sm = float(pi[0]), float(np.sqrt(cov[0, 0]))
    if not m > MASS_SIGMAS * sm or m <= 0:
        raise DataError(f"identify --payload: {where}: the identified mass {m:.4g} ± {sm:.2g} kg: expected a "
                        f"mass more than {MASS_SIGMAS:g} standard deviations above 0 (no payload the data can tell "
                        "from none); is the payload mounted, and do the wrist joints move?")
    x = convert(pi, R, p)
    D = np.zeros((10, 10))
    for k in range(10):
        step = 1e-6 * max(abs(pi[k]), np.sqrt(cov[k, k]), 1e-9)
        e = np.zeros(10)
        e[k] = step
        D[:, k] = (convert(pi + e, R, p) - convert(pi - e, R, p)) / (2 * step)
    C = D @ cov @ D.T
    std = np.sqrt(np.maximum(np.diag(C), 0.0))
    Ic, Ic_std = _sym(x[4:]), _sym(std[4:])
    if not fit.inertia_excited:
        note = "not excited by the motion (the regressor's inertia columns are dependent): mass and centre of mass only"
    else:
        lam = np.linalg.eigvalsh(Ic)
        if lam[0] <= 0 or lam[2] > lam[0] + lam[1]:
            note = (f"not physically consistent (principal moments {', '.join(f'{v:.3g}' for v in lam)} kg m^2: "
                    "expected each > 0 and at most the sum of the other two): mass and centre of mass only")
        elif std[4:].max() > INERTIA_PRECISION * lam[2]:
            note = (f"not determined (an entry's standard deviation {std[4:].max():.2g} kg m^2 is more than "
                    f"{100 * INERTIA_PRECISION:g} % of the largest principal moment {lam[2]:.3g}): mass and centre of "
                    "mass only")
        else:
            note = ""
    ok = not note
    return PayloadResult(mass=m, mass_std=sm, com=x[1:4], com_std=std[1:4], com_cov=C[1:4, 1:4],
                         inertia=Ic if ok else None, inertia_std=Ic_std if ok else None, inertia_note=note, fit=fit)


def _num(x: float) -> float:
    return float(f"{float(x):.{DIGITS}g}") + 0.0


def _item(value, comment: str):
    item = tomlkit.item(value)
    item.comment(comment)
    return item


def payload_text(res: PayloadResult, arm: Arm, source_text: str, source: Path, out: Path,
                 log_name: str) -> tuple[str, list[str]]:
    """(the arm file with ``[payload]`` from ``res``, the notes on what was kept) (module docstring).
    DerivationError if the text does not load as an arm file."""
    doc = tomlkit.parse(source_text)
    old = arm.payload
    notes = []
    table = doc.get("payload")
    if table is None:
        table = tomlkit.table()
        doc.add(tomlkit.nl())
        doc.add(tomlkit.comment(f"identified by derive identify --payload from {log_name}"))
        doc.add("payload", table)
    ident = f"identified {res.mass:.4g} ± {res.mass_std:.2g} kg"
    if old is not None and old.mass >= res.mass:
        mass = old.mass
        table["mass"] = _item(_num(mass), f"{ident}; the file's {old.mass:g} kept (mass is the range's maximum)")
        notes.append(f"mass: {ident}; the file's {old.mass:g} kg kept (the [payload] mass is the largest payload)")
    else:
        mass = _num(res.mass)
        was = f" (was {old.mass:g})" if old is not None else ""
        table["mass"] = _item(mass, f"kg, {ident}{was}")
    com = [_num(c) for c in res.com]
    table["com"] = _item(com, "m, tip link's frame, identified ± " + ", ".join(f"{s:.2g}" for s in res.com_std))
    radius = COM_SIGMAS * res.com_sigma
    if old is not None and old.com_radius > radius:
        table["com_radius"] = _item(old.com_radius, f"m, the file's (>= {COM_SIGMAS:g} sigma = {radius:.2g} m)")
    else:
        table["com_radius"] = _item(_num(radius), f"m, {COM_SIGMAS:g} x the identified com's rms std")
    if res.inertia is not None:
        scaled = res.inertia * (mass / res.mass)
        table["inertia"] = _item([[_num(x) for x in row] for row in scaled],
                                 f"kg m^2 about the com at mass {mass:g} kg (identified at {res.mass:.4g} kg)")
    else:
        notes.append(f"inertia {res.inertia_note}; " + ("the file's kept" if old is not None and old.inertia is not None
                                                        else "none written (the 5 cm sphere applies)"))
    relocate_urdf(doc, source, out)
    text = tomlkit.dumps(doc).rstrip("\n") + "\n"
    data = tomllib.loads(text)
    if "urdf" in data.get("arm", {}):
        data["arm"]["urdf"] = str(urdf_target(source, source_text))
    try:
        arm_from_dict(data, str(out), out.parent)
    except (SpecError, tomllib.TOMLDecodeError) as exc:
        raise DerivationError(f"identify --payload: the arm file with the identified payload does not load ({exc})") \
            from None
    return text, notes


def report_data(res: PayloadResult, logs: list[str], written: str | None, notes: list[str]) -> dict:
    """The report as plain data (payload.json)."""
    f = res.fit
    return jsonio.plain({
        "_note": "generated by derive identify --payload; do not edit", "logs": logs, "arm_file": written,
        "frame": "the tip link's", "mass_kg": res.mass, "mass_std_kg": res.mass_std,
        "com_m": res.com.tolist(), "com_std_m": res.com_std.tolist(), "com_rms_std_m": res.com_sigma,
        "inertia_kg_m2": None if res.inertia is None else res.inertia.tolist(),
        "inertia_std_kg_m2": None if res.inertia_std is None else res.inertia_std.tolist(),
        "inertia_note": res.inertia_note or "identified consistently", "standard_F_n": f.pi.tolist(),
        "equations": f.samples.equations, "condition_number": f.cond,
        "friction": {k: {"value": float(v), "std": float(s)} for k, v, s in
                     zip(f.friction_names, f.friction, f.friction_std)},
        "friction_refused": {str(k): v for k, v in f.refused.items()},
        "rms_residual_file_Nm": f.rms_file.tolist(), "rms_residual_fit_Nm": f.rms_fit.tolist(), "notes": notes})


def report_markdown(data: dict) -> str:
    """payload.md: the figures with their standard deviations."""
    c, s = data["com_m"], data["com_std_m"]
    lines = ["# Payload identification", "", "Generated by derive identify --payload; do not edit.", "",
             f"Logs: {', '.join(data['logs'])}; {data['equations']} torque equations, condition number "
             f"{data['condition_number']:.4g}.", "", "| quantity | value | std |", "| --- | --: | --: |",
             f"| mass [kg] | {data['mass_kg']:.5g} | {data['mass_std_kg']:.2g} |"]
    lines += [f"| com {a} [m] (tip link's frame) | {v:.5g} | {e:.2g} |" for a, v, e in zip("xyz", c, s)]
    if data["inertia_kg_m2"] is not None:
        I, E = data["inertia_kg_m2"], data["inertia_std_kg_m2"]
        lines += [f"| I{'xyz'[a]}{'xyz'[b]} about the com [kg m^2] | {I[a][b]:.4g} | {E[a][b]:.2g} |"
                  for a, b in INERTIA_INDEX]
    lines += [f"| {k} | {v['value']:.4g} | {v['std']:.2g} |" for k, v in data["friction"].items()]
    lines += ["", f"Inertia: {data['inertia_note']}.", "",
              "RMS torque residual per joint [N m], the file without payload -> with the identified one: "
              + ", ".join(f"{a:.3g} -> {b:.3g}" for a, b in zip(data["rms_residual_file_Nm"],
                                                                 data["rms_residual_fit_Nm"]))]
    lines += [f"Joint {k}: no friction identified: {v}." for k, v in data["friction_refused"].items()]
    lines += [f"Note: {x}." for x in data["notes"]]
    lines += ["", f"Arm file: {data['arm_file'] or 'not written'}."]
    return "\n".join(lines) + "\n"


def summary(res: PayloadResult) -> str:
    """The lines derive identify --payload prints."""
    c = ", ".join(f"{x:.4g}" for x in res.com)
    s = ", ".join(f"{x:.2g}" for x in res.com_std)
    lines = [f"payload: mass {res.mass:.4g} ± {res.mass_std:.2g} kg, centre of mass [{c}] ± [{s}] m (tip link's "
             f"frame), from {res.fit.samples.equations} equations, condition number {res.fit.cond:.4g}"]
    if res.inertia is not None:
        lam = np.linalg.eigvalsh(res.inertia)
        lines.append("inertia about the centre of mass: principal moments "
                     + ", ".join(f"{x:.3g}" for x in lam) + " kg m^2")
    else:
        lines.append(f"inertia: {res.inertia_note}")
    lines += [f"{k} = {v:.4g} ± {e:.2g}" for k, v, e in zip(res.fit.friction_names, res.fit.friction,
                                                            res.fit.friction_std)]
    return "\n".join(lines)
