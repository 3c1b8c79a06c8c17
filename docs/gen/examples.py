"""Every code example of the documentation, checked: ``make docs`` fails when one no longer fits.

A fenced block's language decides the check (:func:`check_block`):

- ``sh``: each command line is parsed, not run: a ``derive`` command by derive's own argparse
  parser (an unknown command or option, a bad choice fails), ``make TARGET`` against the Makefile's
  targets, ``python -m MODULE`` against the importable modules (``python -m benchmarks SECTION``
  against its SECTIONS), ``pip install 'derive[X]'``
  against pyproject's extras;
- ``python``: parsed (``ast``); a ``derive.`` attribute path it names must exist (imported);
- ``toml``: parsed (``tomllib``), every table and key checked against the arm-file reference
  (derive.model.keydocs: a renamed key fails);
- ``c`` and ``cmake``: every ``glasgow_2link_*`` / ``GLASGOW_2LINK_*`` name must be declared in the
  committed generated headers or CMakeLists.txt;
- ``text``, ``console`` and others: output, not checked.

A block right after the line ``<!-- docs: run -->`` is also *executed* (:func:`run_block`) in a new
temporary folder with ``.venv/bin`` first on PATH and ``.venv`` linked into it: a shell block by bash
(``set -euo pipefail``), a Python block by the venv's python. A ``<!-- docs: files A B:C -->`` line
beside the marker copies the repository's files A and B there first, B under the name C.
"""
from __future__ import annotations

import ast
import functools
import importlib
import os
import re
import shlex
import shutil
import subprocess
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
ARM = "glasgow_2link"
_FENCE = re.compile(r"^(?P<indent> *)(?P<fence>```+|~~~+)(?P<info>[^`]*)$")
RUN = "<!-- docs: run -->"
FILES = "<!-- docs: files "


@dataclass(frozen=True)
class Block:
    """One fenced code block: ``page`` (relative to docs/), the line of its opening fence, language,
    code, whether it is to be run and the repository files to copy beside it."""

    page: str
    line: int
    lang: str
    code: str
    run: bool = False
    files: tuple[str, ...] = ()

    @property
    def where(self) -> str:
        return f"docs/{self.page}:{self.line}"


def blocks(path: Path) -> list[Block]:
    """The fenced code blocks of a Markdown file."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, lang = m["fence"], m["info"].strip().split(" ")[0].lower()
        markers = [lines[k].strip() for k in range(max(0, i - 3), i)]
        run = RUN in markers
        files = tuple(x for mark in markers if mark.startswith(FILES)
                      for x in mark[len(FILES):].removesuffix("-->").split())
        start, i = i + 1, i + 1
        while i < len(lines) and lines[i].strip() != fence:
            i += 1
        code = "\n".join(line[len(m["indent"]):] for line in lines[start:i])
        page = str(path.relative_to(DOCS)) if path.is_relative_to(DOCS) else path.name
        out.append(Block(page, start, lang, code, run, files))
        i += 1
    return out


def pages() -> list[Path]:
    """The hand-written Markdown pages (the generated reference pages are not on disk)."""
    return sorted(p for p in DOCS.rglob("*.md")
                  if not any(part == "gen" or part.startswith("_") for part in p.relative_to(DOCS).parts))


# -- sh --------------------------------------------------------------------------------------

def commands(code: str) -> list[list[str]]:
    """The command lines of a shell block: comments dropped, continuations joined, split at
    ``&&`` and ``;``, each as shlex words (``$VAR`` left as written)."""
    joined = re.sub(r"\\\n", " ", code)
    out = []
    for line in joined.splitlines():
        words = shlex.split(line, comments=True)
        current: list[str] = []
        for w in words + [";"]:
            if w in ("&&", ";", "||", "|"):
                if current:
                    out.append(current)
                current = []
            else:
                current.append(w)
    return out


@functools.cache
def _make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    return set(re.findall(r"^([a-z][a-z-]*):", text, flags=re.M))


@functools.cache
def _extras() -> set[str]:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return set(data["project"]["optional-dependencies"])


def derive_args(words: list[str]) -> list[str] | None:
    """The arguments of a ``derive`` command line (``derive``, ``.venv/bin/derive``, ``python -m
    derive``), or None when the line runs something else."""
    if words and Path(words[0]).name == "derive":
        return words[1:]
    if len(words) >= 3 and Path(words[0]).name.startswith("python") and words[1:3] == ["-m", "derive"]:
        return words[3:]
    return None


@functools.cache
def _top_parser():
    from derive.cli import command_parsers

    return command_parsers()[0]


def check_derive(args: list[str]) -> str | None:
    """None when derive's parser accepts ``args``; else the parser's complaint."""
    import contextlib
    import io

    if args in (["--version"], ["--help"], ["-h"]) or (args and args[-1] in ("--help", "-h")):
        return None
    top = _top_parser()
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            top.parse_args(args)
    except SystemExit:
        return err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else "rejected"
    return None


def check_sh(code: str) -> list[str]:
    problems = []
    for words in commands(code):
        args = derive_args(words)
        if args is not None:
            if (why := check_derive(args)) is not None:
                problems.append(f"`{shlex.join(words)}`: {why}")
        elif words[0] == "make":
            for target in (w for w in words[1:] if "=" not in w and not w.startswith("-")):
                if target not in _make_targets():
                    problems.append(f"`{shlex.join(words)}`: no make target {target!r}")
        elif Path(words[0]).name.startswith("python") and words[1:2] == ["-m"] and len(words) > 2:
            import importlib.util

            if importlib.util.find_spec(words[2]) is None:
                problems.append(f"`{shlex.join(words)}`: no module {words[2]!r}")
            elif words[2] == "benchmarks":
                from benchmarks.__main__ import SECTIONS

                sections = words[5:] if words[3:4] == ["--json"] else words[3:]   # [--json PATH] SECTION ...
                for section in sections:
                    if section not in SECTIONS:
                        problems.append(f"`{shlex.join(words)}`: no benchmark section {section!r}")
        elif words[:2] == ["pip", "install"]:
            for w in words[2:]:
                if m := re.fullmatch(r"derive\[([a-z,]+)\]", w):
                    problems += [f"`{shlex.join(words)}`: no extra {x!r} in pyproject.toml"
                                 for x in m[1].split(",") if x not in _extras()]
    return problems


# -- python ------------------------------------------------------------------------------------

def check_python(code: str) -> list[str]:
    try:
        tree = ast.parse(code)
    except SyntaxError as exc:
        return [f"not Python: {exc.msg} (line {exc.lineno})"]
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load):
            path = []
            cur: ast.expr = node
            while isinstance(cur, ast.Attribute):
                path.append(cur.attr)
                cur = cur.value
            if isinstance(cur, ast.Name) and cur.id == "derive":
                dotted = ["derive"] + path[::-1]
                if not _resolves(dotted):
                    problems.append(f"{'.'.join(dotted)} does not exist")
    return sorted(set(problems))


def _resolves(dotted: list[str]) -> bool:
    """Whether some prefix of ``dotted`` is a module whose attributes resolve the rest."""
    for k in range(len(dotted), 0, -1):
        try:
            obj = importlib.import_module(".".join(dotted[:k]))
        except ImportError:
            continue
        for attr in dotted[k:]:
            if not hasattr(obj, attr):
                # an attribute of an instance (d.K1) cannot be checked on the class: stop at classes
                return isinstance(obj, type)
            obj = getattr(obj, attr)
        return True
    return False


# -- toml ------------------------------------------------------------------------------------

def check_toml(code: str) -> list[str]:
    from derive.model.keydocs import TABLES

    try:
        data = tomllib.loads(code)
    except tomllib.TOMLDecodeError as exc:
        return [f"not TOML: {exc}"]
    known = {t.header.strip("[]"): {k.name for k in t.keys} for t in TABLES}
    top = known.pop("(top level)")
    problems = []

    def visit(name: str, value: object) -> None:
        tables = value if isinstance(value, list) else [value]
        for table in tables:
            if not isinstance(table, dict):
                continue
            for key, sub in table.items():
                child = f"{name}.{key}"
                if child in known:
                    visit(child, sub)
                elif key not in known[name]:
                    problems.append(f"[{name}] has no key {key!r} (docs/reference/arm-file.md)")

    for key, value in data.items():
        if key not in top:
            problems.append(f"no top-level table {key!r} in an arm file")
        elif key in known:
            visit(key, value)
    return problems


# -- c, cmake --------------------------------------------------------------------------------

@functools.cache
def _declared() -> str:
    folder = ROOT / "generated" / ARM / "c"
    return "\n".join(p.read_text(encoding="utf-8") for p in sorted(folder.glob("*.h"))) + \
        (folder / "CMakeLists.txt").read_text(encoding="utf-8")


def check_c(code: str) -> list[str]:
    declared = set(re.findall(rf"\b(?:{ARM}|{ARM.upper()})_?\w*", _declared()))
    used = set(re.findall(rf"\b(?:{ARM}|{ARM.upper()})_\w+", code))
    return [f"{name} is declared in no generated header nor CMakeLists.txt" for name in sorted(used - declared)]


CHECKS = {"sh": check_sh, "bash": check_sh, "python": check_python, "toml": check_toml, "c": check_c,
          "cmake": check_c}


def check_block(block: Block) -> list[str]:
    """The problems of one block, each prefixed with where it is."""
    check = CHECKS.get(block.lang)
    return [f"{block.where}: {p}" for p in (check(block.code) if check else [])]


def check_all() -> tuple[int, list[str]]:
    """(how many blocks were checked, their problems) over every hand-written page."""
    found = [b for page in pages() for b in blocks(page)]
    return sum(b.lang in CHECKS for b in found), [p for b in found for p in check_block(b)]


# -- run ---------------------------------------------------------------------------------------

def run_block(block: Block, timeout: float = 600) -> str | None:
    """Run a ``<!-- docs: run -->`` block in a new temporary folder; None when it exits 0, else
    its output's tail."""
    with tempfile.TemporaryDirectory(prefix="derive-docs-") as tmp:
        for name in block.files:
            source, _, target = name.partition(":")
            shutil.copy(ROOT / source, Path(tmp) / (target or Path(source).name))
        (Path(tmp) / ".venv").symlink_to(ROOT / ".venv")   # the examples' .venv/bin/derive
        env = dict(os.environ, PATH=f"{ROOT / '.venv' / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}",
                   MPLBACKEND="Agg")
        command = ["python", "-c", block.code] if block.lang == "python" else \
            ["bash", "-c", "set -euo pipefail\n" + block.code]
        done = subprocess.run(command, cwd=tmp, env=env, capture_output=True, text=True, timeout=timeout)
    if done.returncode == 0:
        return None
    tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-15:])
    return f"{block.where}: exit {done.returncode}\n{tail}"


def runnable() -> list[Block]:
    return [b for page in pages() for b in blocks(page) if b.run]
