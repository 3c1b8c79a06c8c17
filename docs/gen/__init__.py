"""The documentation's generated pages and its example checks (used by docs/hooks.py at build time
and by tests/test_docs.py): every page here is computed from derive's own tables, parsers and
generated headers, so it cannot drift from them."""


def cell(text: str | None) -> str:
    """``text`` as one Markdown table cell: on one line, ``|`` escaped, and ``[`` escaped outside code
    spans (``W[i][j]`` would be read as a reference link)."""
    parts = " ".join((text or "").split()).replace("|", "\\|").split("`")
    return "`".join(p if i % 2 else p.replace("[", "\\[") for i, p in enumerate(parts))
