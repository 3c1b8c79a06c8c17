"""The arm-file reference: every table and key with unit, default, range and meaning, from
derive.model.keydocs, checked against the readers' own key sets (keydocs.coverage)."""
from __future__ import annotations

from derive.model import keydocs

from gen import cell




def _anchor(header: str) -> str:
    return "".join(c for c in header if c.isalnum() or c in "._-").replace(".", "-") or "top"


def page() -> str:
    """The Markdown of docs/reference/arm-file.md; raises ValueError when a reader's keys and the
    documented ones differ."""
    problems = keydocs.coverage()
    if problems:
        raise ValueError("the arm-file reference and the readers disagree:\n" + "\n".join(problems))
    lines = ["# Arm-file keys", "",
             "Generated at build time from `derive.model.keydocs`, whose tables the build checks against the "
             "key sets the readers accept (`derive.model.spec.ARM_KEYS`, `CONTROLLER_KEYS`, "
             "`derive.model.simspec.KEYS`, ...): a key no reader accepts, or one the reference lacks, fails "
             "`make docs`. Any other key in a file is an error naming it. *required*: the key must be given; "
             "*-*: leaving it out means none; n is the number of joints.", ""]
    lines += [f"- [`{t.header}`](#{_anchor(t.header)})" for t in keydocs.TABLES]
    for t in keydocs.TABLES:
        lines += ["", f"## `{t.header}` {{#{_anchor(t.header)}}}", "", t.doc, "",
                  "Keys read by " + ", ".join(f"`{r}`" for r in t.reader.split("+") if not r.startswith("="))
                  + "".join(f" and `{r[1:]}`" for r in t.reader.split("+") if r.startswith("=")) + ".", "",
                  "| key | unit | default | range | meaning |", "| --- | --- | --- | --- | --- |"]
        lines += [f"| `{k.name}` | {cell(k.unit)} | {cell(k.default)} | {cell(k.range)} | {cell(k.meaning)} |"
                  for k in t.keys]
    return "\n".join(lines) + "\n"
