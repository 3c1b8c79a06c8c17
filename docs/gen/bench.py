"""The benchmark tables, rendered from docs/data/benchmarks.json (the figures as measured, cell for
cell; see its "_about") where a page says ``<!-- bench: NAME -->``."""
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
    return PLACEHOLDER.sub(lambda m: render(data[m[1]]), markdown)
