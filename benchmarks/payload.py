"""The cost of the payload statement (issue 38): CPU of ``derive check`` on the 7-joint Panda starter file
(tests/data/urdf/panda.toml) as it is and with a ``[payload]`` table (mass 3 kg, the centre of mass within
0.15 m of the flange: what ``derive init --payload 3`` writes, with the file's own W and sample time, so that
the only difference is the statement: the largest payload per form, derive.control.payload.limits, and the
``payload-range`` obligation). Each check runs in its own process (no derivation shared through in-process
caches), one after the other in this run, so the ratio is taken under the same load; the CPU is the child's
(user + system, resource.getrusage), the compiler's included."""
from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from . import Goal, Section, table

TITLE = "Payload statement"
DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "urdf"
PAYLOAD = "\n[payload]\nmass = 3.0\ncom = [0.0, 0.0, 0.0]\ncom_radius = 0.15\n"
GOAL = 30.0   # s: check's budget for 7 joints


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _check(path: Path, folder: Path) -> tuple[float, int, dict]:
    """CPU [s] of ``derive check path --json``, its exit status and its JSON."""
    out = folder / f"{path.stem}.json"
    env = {**os.environ, "DERIVE_CACHE_DIR": str(folder / f"cache-{path.stem}")}   # no cache shared between them
    start = _children_cpu()
    proc = subprocess.run([sys.executable, "-m", "derive", "check", str(path), "--json", str(out)],
                          capture_output=True, text=True, env=env)
    cpu = _children_cpu() - start
    if proc.returncode not in (0, 1) or not out.exists():
        raise RuntimeError(f"derive check {path}: exit {proc.returncode}\n{proc.stderr[-2000:]}")
    return cpu, proc.returncode, json.loads(out.read_text())


def _status(report: dict, ident: str) -> str:
    return next((o["status"] for o in report["obligations"] if o["id"] == ident), "absent")


def run() -> Section:
    with tempfile.TemporaryDirectory(prefix="derive-bench-payload-") as tmp:
        folder = Path(tmp)
        shutil.copy(DATA / "panda.urdf", folder / "panda.urdf")
        text = (DATA / "panda.toml").read_text()
        plain, loaded = folder / "panda.toml", folder / "panda_payload.toml"
        plain.write_text(text)
        loaded.write_text(text + PAYLOAD)
        cpu0, code0, rep0 = _check(plain, folder)
        cpu1, code1, rep1 = _check(loaded, folder)
    limits = rep1.get("payload", {})
    rows = [("panda (7 joints)", "none", f"{cpu0:.1f} s", code0, _status(rep0, "payload-range"), "-"),
            ("panda (7 joints)", "0-3 kg, 0.15 m ball", f"{cpu1:.1f} s", code1, _status(rep1, "payload-range"),
             _limits(limits))]
    block = table(("arm", "[payload]", "check CPU", "exit", "payload-range", "stated limits (forward Euler)"), rows)
    note = (f"Ratio with / without the statement: {cpu1 / cpu0:.2f} (+{cpu1 - cpu0:.1f} s). The Panda starter's "
            "nominal W and sample time are kept (not init --payload's design), so exit 1 with payload-range "
            "failing is the expected verdict: the file's controller does not hold 3 kg; the time is what is measured.")
    goals = (Goal(f"derive check with [payload] under {GOAL:g} s CPU for 7 joints", cpu1 < GOAL,
                  f"{cpu1:.1f} s, {cpu1 / cpu0:.2f} x the check without it ({cpu0:.1f} s)"),)
    return Section(TITLE, (block, note), goals)


def _limits(record: dict) -> str:
    """``form limit`` pairs of check's "payload" record (derive.control.payload.text.record)."""
    return ", ".join(f"{f.upper()} {v['limit_kg']:.3g} kg" for f, v in record["forms"].items())
