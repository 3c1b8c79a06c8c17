"""Run every benchmark section in turn and print Markdown: ``python -m benchmarks [--json PATH] [SECTION ...]``.

To add a section, write ``benchmarks/<name>.py`` with ``TITLE`` and
``run() -> Section`` and list ``"<name>"`` in :data:`SECTIONS`. Goals print as
PASS/MISS and do not change the exit status (timings on a shared machine are
noisy); a section that finds a wrong result raises, and the run fails.

With ``--json PATH`` the run is also recorded as strict JSON (:mod:`derive.jsonio`),
``{"_about": str, "sections": [record, ...]}``, one record per section (see
:func:`record`: module, title, seconds, blocks, goals and the command, UTC date and
versions of the run that measured it), ordered as :data:`SECTIONS`. A run of some
sections merges into an existing file: the sections run replace theirs, the others
are kept with their own dates and versions. The file is written once, after the
last section, through a temporary file renamed over PATH: a section that raises
leaves PATH as it was. docs/gen/bench.py renders a record (``<!-- bench-run: NAME -->``).
"""
from __future__ import annotations

import datetime
import importlib
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

SECTIONS: tuple[str, ...] = ("dynamics", "codegen", "simulation", "mujoco", "observer", "spatial", "identify", "payload",
                             "scaling", "corpus")

ABOUT = ("What `python -m benchmarks --json PATH` measured (`make bench` writes docs/data/bench-run.json): one "
         "record per section, with the blocks (Markdown tables and notes) and goals exactly as the run printed "
         "them, and the command, UTC date and versions of the run that measured that section. A run of some "
         "sections replaces only those. docs/hooks.py renders a section where a page says "
         "<!-- bench-run: NAME -->; committing this file is what updates the documentation's tables.")


def _version(module: str) -> str | None:
    try:
        return importlib.import_module(module).__version__
    except ImportError:
        return None


def environment() -> dict[str, Any]:
    """The machine and versions of this run: python, sympy, numpy, casadi (None if absent), machine, cpus."""
    return {"python": platform.python_version(), "sympy": _version("sympy"), "numpy": _version("numpy"),
            "casadi": _version("casadi"), "machine": platform.machine(), "cpus": os.cpu_count()}


def record(name: str, section, seconds: float, command: str, date: str, env: dict[str, Any]) -> dict[str, Any]:
    """The JSON record of one section run: what the ``Section`` holds, its time and the run's environment."""
    return {"module": name, "title": section.title, "seconds": round(seconds, 1), "blocks": list(section.blocks),
            "goals": [{"text": g.text, "met": g.met, "measured": g.measured} for g in section.goals],
            "command": command, "date": date, **env}


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def read(path: Path) -> dict[str, dict[str, Any]]:
    """{module: record} of an existing snapshot at ``path`` ({} if there is none); ValueError if it is not
    strict JSON of this layout."""
    from derive.jsonio import loads

    if not path.exists():
        return {}
    data = loads(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict) or not isinstance(data.get("sections"), list):
        raise ValueError(f"{path}: not a benchmark snapshot (no list 'sections')")
    return {s["module"]: s for s in data["sections"]}


def write(path: Path, records: dict[str, dict[str, Any]]) -> None:
    """Merge ``records`` into the snapshot at ``path`` (re-read now) and write it atomically."""
    from derive.jsonio import dumps

    merged = {**read(path), **records}
    order = {name: i for i, name in enumerate(SECTIONS)}
    sections = sorted(merged.values(), key=lambda s: (order.get(s["module"], len(order)), s["module"]))
    text = dumps({"_about": ABOUT, "sections": sections})
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def main(names: tuple[str, ...] = SECTIONS, json_path: str | Path | None = None, command: str | None = None) -> int:
    """Run the sections ``names`` (modules of this package), printing each as it finishes; with
    ``json_path``, merge their records into that snapshot after the last one (nothing written if one raises)."""
    import sympy

    path = None if json_path is None else Path(json_path)
    if path is not None:
        read(path)   # a broken snapshot fails now, not after an hour of benchmarks
    command = command or " ".join(["python -m benchmarks", *(["--json", str(path)] if path else []), *names])
    env = environment()
    print(f"# derive benchmarks\n\nPython {platform.python_version()}, SymPy {sympy.__version__}, "
          f"{platform.machine()}\n", flush=True)
    misses = 0
    records = {}
    for name in names:
        module = importlib.import_module(f"{__package__}.{name}")
        date = _now()
        start = time.perf_counter()
        section = module.run()
        seconds = time.perf_counter() - start
        print(section.markdown(), flush=True)
        print(f"_{module.TITLE}: {seconds:.1f} s_\n", flush=True)
        misses += sum(not g.met for g in section.goals)
        records[name] = record(name, section, seconds, command, date, env)
    print(f"{misses} goal(s) missed." if misses else "All goals met.")
    if path is not None:
        write(path, records)
        print(f"Wrote {path} ({', '.join(records)}).", file=sys.stderr)
    return 0


def cli(argv: list[str]) -> int:
    """``[--json PATH] [SECTION ...]``: no section names run every section; an unknown name is an error (exit 2)."""
    json_path = None
    if argv[:1] == ["--json"]:
        if len(argv) < 2:
            print("usage: python -m benchmarks [--json PATH] [SECTION ...]", file=sys.stderr)
            return 2
        json_path, argv = argv[1], argv[2:]
    unknown = [a for a in argv if a not in SECTIONS]
    if unknown:
        print(f"unknown section(s) {', '.join(unknown)}; the sections are {', '.join(SECTIONS)}", file=sys.stderr)
        return 2
    names = tuple(argv) or SECTIONS
    return main(names, json_path, " ".join(["python -m benchmarks", *sys.argv[1:]]))


if __name__ == "__main__":
    sys.exit(cli(sys.argv[1:]))
