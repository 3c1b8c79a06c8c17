"""The corpus's sample-time columns (issue 34, "How it is shown"): benchmarks/limits_truth.py run on each
arm file (benchmarks/corpus.py runs it in a process of its own), its table of stated / true limits, the points where a stated limit is
above, and the goals (stated stable at every steady point, where the frozen-time loop is exact; stated <=
true; within 1.5x). Used by benchmarks/corpus.py."""
from __future__ import annotations

from benchmarks import Goal, table

LIMIT_FORMS = ("MPC", "DOBC", "NPID", "MOM", "DOBC-i", "NPID-i")   # benchmarks.limits_truth's labels


def limits_markdown(limited: list) -> list[str]:
    """The table, its caption and the points above, for the arms whose limits ran."""
    above = [f"- {r.name} {x['label']}: stated {x['stated'] * 1e3:.4g} ms, true {x['true'] * 1e3:.4g} ms "
             f"(rho {x['rho_stated']:.4f} at the stated limit, at a point {x['kind']}: theta {_point(x['worst'][0])}, "
             f"theta' {_point(x['worst'][1])})" for r in limited for x in _limit_rows(r) if _above(x)]
    return [table(("arm", "joints", "starter dt") + LIMIT_FORMS, [_limits_row(r) for r in limited]),
            "Sample-time limits [ms], stated / true (true / stated): stated as derive check prints it (0.9 of the "
            "largest stable sample time over derive's grid); true the largest at which the linearised sampled loop "
            "is stable at every point of a denser set (benchmarks/limits_truth.py: the grid's configurations and 3x "
            "more times its speeds and the cyclic joints' spins, 4096 more at rest, a local search; no margin, "
            "bisected to 0.2 %). -i: the implicit observer step. Starter dt: the arm file's sample time and "
            "observer step. ABOVE: unstable at a steady point (rest or spin: the frozen-time loop exact); "
            "above (moving): only at points in motion, where both figures are frozen-time.",
            "Stated above the true limit:\n\n" + "\n".join(above) if above else "No stated limit above the true one."]


def _limit_rows(result) -> list[dict]:
    return [dict(x, label=x["form"].upper() + ("-i" if x["observer"] == "implicit" else ""))
            for x in (result.limits or {}).get("rows", [])]


def _above(x: dict) -> bool:
    """A stated limit above the true one, or unstable at a point of the dense set (limits_truth.Truth)."""
    return x["stated"] > x["true"] or not x["rho_stated"] < 1.0


def _steady_above(x: dict) -> bool:
    """The stated limit unstable at a steady point of the dense set (limits_truth.Truth.steady_violation)."""
    return not x.get("rho_steady", float("nan")) < 1.0


def _point(v) -> str:
    return "(" + ", ".join(f"{a:.4g}" for a in v) + ")"


def _ms(x: float) -> str:
    return "-" if not x or x != x else "inf" if x == float("inf") else f"{x * 1e3:.4g}"


def _limits_row(result) -> list:
    rows = {x["label"]: x for x in _limit_rows(result)}
    lim = result.limits
    cells = [f"{_ms(x['stated'])} / {_ms(x['true'])} ({x['ratio']:.3g})" + (" ABOVE" if _steady_above(x) else " above (moving)" if _above(x) else "")
             if (x := rows.get(f)) else "-" for f in LIMIT_FORMS]
    return [result.name, result.joints, f"{lim['sample_time'] * 1e3:g} ms {lim['observer']}"] + cells


def limit_goals(results: list) -> list[Goal]:
    """Issue 34's: every stated sample-time limit at most the true one, and within 1.5x of it, per form."""
    rows = [(r.name, x) for r in results for x in _limit_rows(r)]
    if not rows:
        return []
    above = [f"{name} {x['label']} {x['ratio']:.3g}" for name, x in rows if _above(x)]
    steady = [f"{name} {x['label']} (rho {x['rho_steady']:.4f})" for name, x in rows if _steady_above(x)]
    out = [Goal("stated sample-time limit stable at every steady point (rest, spin: the frozen-time loop exact)",
                not steady, f"unstable on {len(steady)} of {len(rows)}: {', '.join(steady)}" if steady
                else f"{len(rows)} limits"),
           Goal("stated sample-time limit <= true for every form and arm (moving points: frozen-time figures)",
                not above, f"above on {len(above)} of {len(rows)}: {', '.join(above)}" if above else f"{len(rows)} limits")]
    for form in LIMIT_FORMS:
        ratios = [(name, x["ratio"], _above(x)) for name, x in rows if x["label"] == form and x["ratio"] == x["ratio"]]
        if ratios:
            far = [f"{name} {q:.3g}" for name, q, _ in ratios if q > 1.5]
            low = min(ratios, key=lambda t: t[1])
            out.append(Goal(f"{form}: stated within 1.5x of the true limit and never above, every arm",
                            not far and not any(a for _, _, a in ratios),
                            f"true / stated {low[1]:.3g} ({low[0]}) to {max(q for _, q, _ in ratios):.3g}"
                            + (f"; beyond 1.5x: {', '.join(far)}" if far else "")))
    return out
