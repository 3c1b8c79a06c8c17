"""The report of derive identify: strict JSON, Markdown and two figures.

``identification.json`` (strict: derive.jsonio), ``identification.md``,
``torques.png`` (per joint: the torque J theta'' + G from the log beside what each
estimate predicts, and the residuals; every k-th row, at most PLOTTED per line) and ``parameters.png`` (each base parameter:
the arm file's value, the least-squares estimate +- 3 standard deviations and the
physically consistent one, relative to the largest of them in magnitude).
"""
from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from derive import jsonio  # noqa: E402
from derive.identify.consistent import TOLERANCE  # noqa: E402
from derive.identify.run import Identification  # noqa: E402
from derive.identify.signals import ORDER  # noqa: E402

PLOTTED = 2000  # points per line of torques.png at most (every k-th row)
DIGITS = 7      # significant digits of the report's figures (deterministic across machines)
RULES = ("valid", "ends", "brake", "zeros", "saturated")
METHOD = ("Least squares: ordinary, then each joint's rows weighted by 1/sigma_j from its residual (Gautier and "
          "Khalil 1992); standard deviations from s^2 (W_w^T W_w)^-1. Consistent: the maximum a posteriori estimate "
          "of the standard parameters, the weighted residual plus a Gaussian prior at the arm file's values with "
          "the standard deviations of the table (--prior-uncertainty), with every body's pseudo-inertia positive "
          "semidefinite (Wensing, Kim, Slotine, IEEE RA-L 2017), rotor inertias >= 0, viscous friction >= 0; "
          "cvxpy with Clarabel.")


def coefficient_text(expression) -> str:
    """A base parameter's expression with each coefficient at DIGITS significant digits
    (``Ia1 + Izz1 + 0.1444*m2``), never an exact rational of many digits."""
    import sympy as sp

    terms = []
    for symbol in sorted(expression.free_symbols, key=lambda x: x.name):
        c = float(expression.coeff(symbol))
        if c == 0:
            continue
        size = "" if abs(c) == 1 else f"{abs(c):.{DIGITS}g}*"
        terms.append(("-" if c < 0 else "+", size + symbol.name))
    rest = float(expression.subs({x: 0 for x in expression.free_symbols})) if expression.free_symbols else \
        float(sp.sympify(expression))
    if rest or not terms:
        terms.append(("-" if rest < 0 else "+", f"{abs(rest):.{DIGITS}g}"))
    return (("-" if terms[0][0] == "-" else "") + terms[0][1] + "".join(f" {s} {t}" for s, t in terms[1:]))


def report_data(idn: Identification, logs: list[str], out_name: str | None, found=()) -> dict:
    """Everything the report states, as plain data (numbers, strings, lists); ``out_name``
    None: the arm file was not written (``found``: derive.identify.quality's findings)."""
    s, ls, cons, model = idn.samples, idn.ls, idn.cons, idn.model
    exprs = [coefficient_text(b.expression) for b in idn.reg.base] + list(idn.names[idn.reg.p:])
    base = [{"name": name, "expression": expr, "unit": unit, "prior": float(p), "least_squares": float(v),
             "std": float(sd), "relative_std_percent": float(r) if np.isfinite(r) else None,
             **({} if np.isfinite(r) else {"relative_std_percent_undefined": "the estimate is 0"}),
             "consistent": float(c)}
            for name, expr, unit, p, v, sd, r, c in zip(idn.names, exprs, idn.units, idn.prior_pi, ls.pi, ls.std,
                                                          ls.relative_std, cons.pi)]
    extra = len(idn.phi0) - len(idn.reg.standard)             # fc1..n under --coulomb
    names = [p.name for p in idn.reg.standard] + [f"fc{j + 1}" for j in range(extra)]
    units = [p.unit for p in idn.reg.standard] + ["N m" if j.type.rotates else "N"
                                                  for j in idn.arm.chain.joints[:extra]]
    standard = [{"name": name, "unit": unit, "prior": float(a), "consistent": float(b)}
                for name, unit, a, b in zip(names, units, idn.phi0, cons.phi)]
    variables = [{"name": name, "prior": float(a), "prior_std": float(sd), "consistent": float(b),
                  "held": bool(sd == 0), **({} if sd == 0 else {"deviation_in_std": float(x), "data_share": float(sh)})}
                 for name, a, sd, b, x, sh in zip(model.names, model.z0, model.S, cons.z, cons.x, idn.share)]
    torque = np.sqrt((np.where(s.use, s.y, 0.0) ** 2).sum(axis=0) / np.maximum(s.use.sum(axis=0), 1))
    joints = [{"joint": j + 1, "equations": int(s.use[:, j].sum()), "sigma": float(ls.sigma[j]),
               "rms_least_squares": float(a), "rms_consistent": float(b), "rms_torque": float(c),
               "explained_least_squares": float(d), "explained_consistent": float(e)}
              for j, (a, b, c, d, e) in enumerate(zip(idn.rms(idn.predicted_ls), idn.rms(idn.predicted_cons), torque,
                                                      idn.explained(idn.predicted_ls),
                                                      idn.explained(idn.predicted_cons)))]
    runs = [{"log": name, "sample_rate_hz": r.rate, "samples": r.samples,
             "removed": {k: r.removed[k] for k in RULES if k in r.removed},
             **{k: r.removed[k] for k in ("zeros_per_joint", "saturated_per_joint") if k in r.removed},
             "joins": r.joins, "gaps_in_time": r.gaps, "stretches": r.stretches, "decimation": r.decimation, "dropped_at_each_end": r.edge, "rows": r.rows,
             "equations": r.equations} for name, r in zip(logs, s.runs)]
    return {
        "_note": "generated by derive identify; do not edit",
        "arm": idn.arm.name, "logs": runs, "arm_file_written": out_name,
        "exclude": idn.rules.text(),
        "filter": {"kind": f"Butterworth order {ORDER}, zero-phase (sosfiltfilt), each stretch of kept samples on "
                           "its own", "cutoff_hz": s.cutoff},
        "rows": {"samples": len(s.t), "equations": ls.rows, "parameters": len(idn.names)},
        "condition_number": ls.cond,
        "coulomb": idn.coulomb,
        "coulomb_not_identified": {str(j): why for j, why in sorted(idn.friction_refused.items())},
        "joints": joints,
        "base_parameters": base,
        "standard_parameters": standard,
        "prior": {"relative_uncertainty": idn.uncertainty, "variables": variables},
        "consistent": {"status": cons.status, "status_words": cons.words, "iterations": cons.iterations,
                       "tolerance": TOLERANCE, "lmi_min_eigenvalues_scaled": list(cons.min_eigenvalues)},
        "findings": [{"kind": f.kind, "rule": f.rule, "text": f.text} for f in found],
        "method": METHOD,
    }


def report_json(data: dict) -> str:
    """Strict JSON of :func:`report_data` at DIGITS significant digits."""
    return jsonio.dumps(jsonio.plain(data, DIGITS))


def _removed(run: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in run["removed"].items()) or "none"


def report_markdown(data: dict) -> str:
    """The Markdown report (figures at 4 significant digits)."""
    f, c = data["filter"], data["consistent"]
    written = f"`{data['arm_file_written']}`" if data["arm_file_written"] else "no arm file (see the findings)"
    lines = ["<!-- generated by derive identify; do not edit -->", f"# Identification: {data['arm']}", "",
             f"{len(data['logs'])} log{'s' if len(data['logs']) > 1 else ''}, each filtered on its own ({f['kind']} "
             f"at {f['cutoff_hz']:g} Hz); exclusion rules: {data['exclude']}. {data['rows']['samples']} rows, "
             f"{data['rows']['equations']} equations for {data['rows']['parameters']} base parameters; condition "
             f"number of the stacked regressor {data['condition_number']:.4g}. Written: {written}.", "",
             "| log | rate [Hz] | samples | removed (samples; zeros, saturated: torque values) | joins | stretches | "
             "decimation | rows | equations |", "| --- | --: | --: | --- | --: | --: | --: | --: | --: |"]
    lines += [f"| `{r['log']}` | {r['sample_rate_hz']:.6g} | {r['samples']} | {_removed(r)} | {r['joins']} | "
              f"{r['stretches']} | {r['decimation']} | {r['rows']} | {r['equations']} |" for r in data["logs"]]
    if data["findings"]:
        lines += ["", "## Findings", ""] + [f"- **{x['kind']}** ({x['rule']}): {x['text']}" for x in data["findings"]]
    lines += ["", "## Per joint", "",
              "| joint | equations | noise sigma [N m] | residual RMS, least squares | consistent | RMS torque | "
              "explained, least squares | consistent |", "| --: | --: | --: | --: | --: | --: | --: | --: |"]
    lines += [f"| {j['joint']} | {j['equations']} | {j['sigma']:.4g} | {j['rms_least_squares']:.4g} | "
              f"{j['rms_consistent']:.4g} | {j['rms_torque']:.4g} | {100 * j['explained_least_squares']:.1f} % | "
              f"{100 * j['explained_consistent']:.1f} % |" for j in data["joints"]]
    lines += ["", "## Base parameters", "",
              "| name | = | unit | arm file | least squares | std | rel. std % | consistent |",
              "| --- | --- | --- | --: | --: | --: | --: | --: |"]
    for b in data["base_parameters"]:
        rel = "n/a" if b["relative_std_percent"] is None else f"{b['relative_std_percent']:.3g}"
        lines.append(f"| {b['name']} | `{b['expression']}` | {b['unit']} | {b['prior']:.4g} | "
                     f"{b['least_squares']:.4g} | {b['std']:.2g} | {rel} | {b['consistent']:.4g} |")
    lines += ["", "## Physically consistent estimate", "",
              f"Solver: **{c['status']}**, {c['status_words']} ({c['iterations']} iterations). Smallest eigenvalue "
              "of each body's LMI matrix, scaled to the body (0: on the boundary of what is physical): "
              + ", ".join(f"{x:.3g}" for x in c["lmi_min_eigenvalues_scaled"]) + ".", "",
              f"Prior: the arm file's values, relative uncertainty {data['prior']['relative_uncertainty']:g} "
              "(--prior-uncertainty). Deviation: (consistent - arm file) / prior std; data share: how much of what "
              "is known of the parameter the data gives (0: nothing, the prior holds it; 1: all).", "",
              "| name | arm file | prior std | consistent | deviation | data share |", "| --- | --: | --: | --: | --: | --: |"]
    for v in data["prior"]["variables"]:
        dev = "held" if v["held"] else f"{v['deviation_in_std']:+.3g}"
        share = "" if v["held"] else f"{v['data_share']:.3f}"
        lines.append(f"| {v['name']} | {v['prior']:.4g} | {v['prior_std']:.3g} | {v['consistent']:.4g} | {dev} | "
                     f"{share} |")
    lines += ["", "![torques](torques.png)", "", "![parameters](parameters.png)", "", "Method: " + data["method"], ""]
    return "\n".join(lines)


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def torque_figure(idn: Identification) -> bytes:
    """Per joint: measured and predicted torque over time, and the residuals."""
    s, n = idn.samples, idn.reg.n
    k = slice(None, None, max(1, len(s.t) // PLOTTED))     # a line of at most about PLOTTED points
    t = _time(s)[k]
    fig, axes = plt.subplots(n, 2, figsize=(11, 2.2 * n + 0.8), sharex=True, squeeze=False)
    for j in range(n):
        ax, res = axes[j]
        used = np.where(s.use[k, j], 1.0, np.nan)        # gaps where the torque was not used
        y = s.y[k, j] * used
        ax.plot(t, y, color="k", lw=1.2, label="from the log")
        ax.plot(t, idn.predicted_ls[k, j] * used, color="tab:blue", lw=0.8, ls="--", label="least squares")
        ax.plot(t, idn.predicted_cons[k, j] * used, color="tab:orange", lw=0.8, ls=":", label="consistent")
        ax.set_ylabel(f"joint {j + 1} [N m]")
        res.plot(t, y - idn.predicted_ls[k, j], color="tab:blue", lw=0.6)
        res.plot(t, y - idn.predicted_cons[k, j], color="tab:orange", lw=0.6)
        res.set_ylabel("residual [N m]")
        for a in (ax, res):
            a.grid(True, lw=0.3)
    axes[0][0].legend(loc="upper right", fontsize=7)
    axes[0][0].set_title("J theta'' + G")
    axes[0][1].set_title("residual")
    label = "t [s]" if len(s.runs) == 1 else "t [s], the logs one after the other"
    axes[-1][0].set_xlabel(label)
    axes[-1][1].set_xlabel(label)
    fig.tight_layout()
    return _png(fig)


def _time(s) -> np.ndarray:
    """Each row's time, the logs laid one after the other (each starting where the last ended)."""
    t = s.t.astype(float).copy()
    offset = 0.0
    for r in range(len(s.runs)):
        rows = s.run == r
        if rows.any():
            t[rows] += offset - t[rows][0]
            offset = float(t[rows][-1]) + 1.0 / s.runs[r].rate
    return t


def parameter_figure(idn: Identification) -> bytes:
    """Each base parameter: arm file, least squares +- 3 std, consistent (scaled per parameter)."""
    ls, p = idn.ls, len(idn.names)
    scale = np.maximum.reduce([np.abs(idn.prior_pi), np.abs(ls.pi), np.abs(idn.cons.pi)])
    scale = np.where(scale > 0, scale, 1.0)
    x = np.arange(p)
    fig, ax = plt.subplots(figsize=(max(6.0, 0.32 * p + 2), 4))
    ax.bar(x - 0.25, idn.prior_pi / scale, width=0.25, color="tab:gray", label="arm file")
    ax.bar(x, ls.pi / scale, width=0.25, yerr=3 * ls.std / scale, color="tab:blue", ecolor="k", capsize=2,
           label="least squares +- 3 std")
    ax.bar(x + 0.25, idn.cons.pi / scale, width=0.25, color="tab:orange", label="consistent")
    ax.set_xticks(x, idn.names, rotation=90, fontsize=7)
    ax.set_ylabel("value / largest |value|")
    ax.grid(True, axis="y", lw=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return _png(fig)
