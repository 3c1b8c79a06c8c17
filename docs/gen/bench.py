"""The benchmark tables of the documentation, rendered where a page says so:

- ``<!-- bench-run: SECTION -->``: that section of the last ``make bench`` run, from the committed
  docs/data/bench-run.json (``python -m benchmarks --json``; one record per section), its blocks and
  goals exactly as ``python -m benchmarks`` printed them, without the section's heading (the page has
  its own), and a line naming the run's date, machine and versions;
- ``<!-- bench: NAME -->``: a typed table of docs/data/benchmarks.json (figures from commands other
  than ``python -m benchmarks``, cell for cell; see its "_about");
- ``<!-- metrics: default experiment -->``: the default experiment's metrics from the committed
  generated/glasgow_2link/sim/metrics.json.

A placeholder naming no table or section raises KeyError (:class:`MissingRun` for a section).
"""
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
    """``markdown`` with every placeholder replaced by its table (KeyError: no such table; MissingRun,
    a KeyError: no such section in bench-run.json)."""
    data = tables()
    markdown = METRICS_PLACEHOLDER.sub(lambda m: metrics_table(), markdown)
    if RUN_PLACEHOLDER.search(markdown):
        sections = runs()
        markdown = RUN_PLACEHOLDER.sub(lambda m: render_run(section(sections, m[1])), markdown)
    return PLACEHOLDER.sub(lambda m: render(data[m[1]]), markdown)


# -- the sections of `make bench`, from the snapshot `python -m benchmarks --json` writes --

RUN = DATA.parent / "bench-run.json"
RUN_PLACEHOLDER = re.compile(r"^<!-- bench-run: ([a-z0-9_]+) -->$", re.M)


class MissingRun(KeyError):
    """A ``<!-- bench-run: SECTION -->`` whose section the snapshot does not hold."""


def runs(path: Path = RUN) -> dict[str, dict]:
    """{module: record} of the snapshot (strict JSON, derive.jsonio; ValueError if it is not)."""
    from derive.jsonio import loads

    return {record["module"]: record for record in loads(path.read_text(encoding="utf-8"))["sections"]}


def section(sections: dict[str, dict], name: str) -> dict:
    """The record of section ``name`` (MissingRun naming it and the sections there are)."""
    if name not in sections:
        raise MissingRun(f"no section {name!r} in docs/data/bench-run.json (it holds {', '.join(sections)}; "
                         f"`python -m benchmarks --json docs/data/bench-run.json {name}` adds it)")
    return sections[name]


_CODE_OR_TAG = re.compile(r"(`+)(.*?)\1|<(?=[A-Za-z/!?])", re.S)


def tag_safe(markdown: str) -> str:
    """``markdown`` with every ``<`` that would open an HTML tag (``<string>`` in a traceback a table quotes)
    written ``&lt;``, outside code spans: the page shows the text as printed."""
    return _CODE_OR_TAG.sub(lambda m: m.group(0) if m.group(1) else "&lt;", markdown)


def render_run(record: dict) -> str:
    """A section's record as ``python -m benchmarks`` printed it, without its ``## title`` line, and the
    line naming the run: date (UTC day), machine, CPUs, Python and SymPy."""
    from benchmarks import Goal, Section

    printed = Section(record["title"], tuple(record["blocks"]), tuple(Goal(**g) for g in record["goals"]))
    return (f"{tag_safe(printed.body())}\n*Measured by `make bench` (`python -m benchmarks {record['module']}`) on "
            f"{record['date'][:10]}, {record['machine']} ({record['cpus']} CPUs), Python {record['python']}, "
            f"SymPy {record['sympy']}.*")


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
