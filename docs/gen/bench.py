"""The benchmark tables, rendered from docs/data/benchmarks.json (the figures as measured, cell for
cell; see its "_about") where a page says ``<!-- bench: NAME -->``, and the default experiment's
metrics from the committed generated/glasgow_2link/sim/metrics.json where it says
``<!-- metrics: default experiment -->``."""
from __future__ import annotations

import json
import re
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data" / "benchmarks.json"
PLACEHOLDER = re.compile(r"^<!-- bench: ([a-z0-9_]+) -->$", re.M)


def tables() -> dict[str, dict]:
    return json.loads(DATA.read_text(encoding="utf-8"))["tables"]


def render(table: dict) -> str:
    """One table as Markdown, its cells verbatim, its source below it."""
    rows = [table["columns"], table["align"], *table["rows"]]
    for row in rows:
        if len(row) != len(table["columns"]):
            raise ValueError(f"a row of {len(row)} cells in a table of {len(table['columns'])} columns: {row}")
    body = "\n".join("| " + " | ".join(row) + " |" for row in rows)
    return f"{body}\n\n*Measured with `{table['source']}`.*"


def substitute(markdown: str) -> str:
    """``markdown`` with every placeholder replaced by its table (KeyError: no such table)."""
    data = tables()
    markdown = METRICS_PLACEHOLDER.sub(lambda m: metrics_table(), markdown)
    return PLACEHOLDER.sub(lambda m: render(data[m[1]]), markdown)


# -- the default experiment's metrics, from the committed metrics.json that `make generate` writes --

METRICS = Path(__file__).resolve().parents[2] / "generated" / "glasgow_2link" / "sim" / "metrics.json"
METRICS_PLACEHOLDER = re.compile(r"^<!-- metrics: default experiment -->$", re.M)
FORMS = (("mpc", "MPC (eq. 15)"), ("dobc", "DOBC (eq. 27)"), ("npid", "NPID (eq. 34)"),
         ("mom", "MOM (momentum observer)"))


def short(x: float) -> str:
    """Two significant digits, the exponent without padding: 8.9e-4."""
    mantissa, exponent = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def metrics_table(path: Path = METRICS) -> str:
    """The default experiment's steady-state and RMS error per form and link."""
    forms = json.loads(path.read_text(encoding="utf-8"))["controllers"]
    rows = ["| controller | link | steady-state error [rad] | RMS error [rad] |", "| --- | --- | --- | --- |"]
    for key, label in FORMS:
        links = forms[key]["links"]
        rows.append(f"| {label} | {' / '.join(str(i) for i in range(1, len(links) + 1))} | "
                    f"{' / '.join(short(x['steady_state_error']) for x in links)} | "
                    f"{' / '.join(short(x['rms_error']) for x in links)} |")
    return "\n".join(rows) + ("\n\n*From the committed `generated/glasgow_2link/sim/metrics.json` "
                              "(`make generate`).*")
