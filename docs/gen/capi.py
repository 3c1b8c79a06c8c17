"""The C API reference, from the committed generated headers (generated/<arm>/c/*.h): each
declaration with the comment the generator wrote above it."""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ARM = "glasgow_2link"
HEADERS = (f"{ARM}.h", f"{ARM}_plant.h")


def blocks(text: str) -> tuple[str, list[tuple[str, str]]]:
    """(the file's opening comment, [(comment, declarations), ...]) of a generated header: its
    paragraphs (split at blank lines), each's leading comment apart from the declarations under it
    (either may be empty); include guards, #include and extern "C" lines are left out."""
    lines = text.splitlines()
    i = 0
    if lines and lines[0].startswith("/*"):
        while not lines[i].rstrip().endswith("*/"):
            i += 1
        i += 1
    preamble = "\n".join(lines[:i])
    guard = ("#ifndef", "#ifdef", "#endif", "#include", "#else", 'extern "C"')
    out = []
    for paragraph in "\n".join(lines[i:]).split("\n\n"):
        kept = [line for line in paragraph.splitlines() if line.strip() and not (
            line.strip().startswith(guard) or line.strip() == "}" or (line.startswith("#define") and line.split()[1].endswith("_H")))]
        comment: list[str] = []
        while kept and (comment and not comment[-1].rstrip().endswith("*/") or kept[0].lstrip().startswith("/*")):
            comment.append(kept.pop(0))
        if comment or kept:
            out.append(("\n".join(comment), "\n".join(kept)))
    return preamble, out


def _strip(comment: str) -> str:
    out = []
    for line in comment.splitlines():
        s = line.strip()
        for token in ("/*", "*/"):
            s = s.replace(token, "")
        s = s.lstrip("*").strip() if s.startswith("*") else s.strip()
        out.append(s)
    return " ".join(x for x in out if x)


def page(root: Path = ROOT) -> str:
    """The Markdown of docs/reference/c-api.md."""
    lines = ["# C API", "",
             f"Generated at build time from the committed headers of the default arm, `generated/{ARM}/c/`: "
             f"each declaration with the comment `derive generate` wrote above it. Another arm's names carry its "
             f"own prefix instead of `{ARM}` (and `{ARM.upper()}` in macros); `--real float` makes "
             f"`{ARM}_real` a `float`, `--params runtime` adds a `const {ARM}_params *` first argument to every "
             f"function. The kernels (`{ARM}_kernels.h`) are internal: call the functions below.", ""]
    for name in HEADERS:
        path = root / "generated" / ARM / "c" / name
        preamble, decls = blocks(path.read_text(encoding="utf-8"))
        lines += [f"## `{name}`", "", "```c", preamble, "```", ""]
        for comment, decl in decls:
            if comment:
                lines += [_strip(comment), ""]
            if decl:
                lines += ["```c", decl, "```", ""]
    return "\n".join(lines)
