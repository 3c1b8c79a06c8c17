"""Cost in the number of joints: synthetic n-joint chains through init, show, check, generate.

``python -m benchmarks.scaling [N ...]`` (default: 2 4 6 8 10 12 16 20; a section of ``make bench``)
writes the snake chain of benchmarks/chains.py with n joints, runs ``derive init`` on it and then
``show``, ``check`` and ``generate`` on the arm file, each in a process of its own started through
benchmarks/peak.py (CPU seconds of the command's process, its peak resident memory), and fits the
growth: the exponent p of CPU ~ n^p by least squares on log-log from 8 joints on (the issue's
goal: p <= 4 for every command). A pair of 7-joint chains, one with its frames written as
``rpy="1.5708 0 -0.7854"`` and one with pi/2, -pi/4 to 17 digits, measures the cost of 4-digit
decimals: the ratio of their init CPU. Ratios and exponents, not timed assertions: the figures
of a shared machine are noisy.
"""
from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

from benchmarks import Goal, Section, table
from benchmarks.chains import snake_urdf
from benchmarks.corpus import run_command

TITLE = "Scaling in joints: synthetic chains through init, show, check, generate"
SIZES = (2, 4, 6, 8, 10, 12, 16, 20)
COMMANDS = ("init", "show", "check", "generate")
TIMEOUT = 1800.0
GOAL_EXPONENT = 4.0


def _derive(*args: str) -> list[str]:
    return [sys.executable, "-m", "derive", *args]


def measure(n: int, folder: Path, decimal: bool = False, exact_rpy: bool = False,
            commands=COMMANDS) -> dict[str, tuple[int | None, float, float]]:
    """{command: (exit code, CPU s, peak MiB)} of the n-joint chain in ``folder``."""
    name = f"snake{n}" + ("d" if decimal else "x" if exact_rpy else "")
    (folder / f"{name}.urdf").write_text(snake_urdf(n, decimal, exact_rpy), encoding="utf-8")
    out = {}
    argv = {"init": _derive("init", f"{name}.urdf", "--name", name),
            "show": _derive("show", f"{name}.toml", "--no-cache"),
            "check": _derive("check", f"{name}.toml"),
            "generate": _derive("generate", f"{name}.toml", "--out", "gen")}
    for command in commands:
        code, _, peak, text, cpu = run_command(argv[command], folder, TIMEOUT)
        out[command] = (code, cpu, peak, text.strip().splitlines()[-1:] if code else [])
        print(f"  {name} {command}: exit {code}, {cpu:.1f} s CPU, {peak:.0f} MiB", file=sys.stderr, flush=True)
        if command == "init" and code != 0:
            break
    return out


def exponent(ns, values) -> float:
    """p of value ~ c n^p (least squares on logs) over the points with n >= 8 (all when fewer than 2)."""
    pts = [(math.log(n), math.log(max(v, 1e-3))) for n, v in zip(ns, values) if n >= 8 and v is not None]
    if len(pts) < 2:
        pts = [(math.log(n), math.log(max(v, 1e-3))) for n, v in zip(ns, values) if v is not None]
    if len(pts) < 2:
        return math.nan
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    sxx = sum((x - mx) ** 2 for x, _ in pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sxx if sxx else math.nan


def run(sizes=SIZES) -> Section:
    rows, cpu = [], {c: [] for c in COMMANDS}
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            folder = Path(tmp) / f"n{n}"
            folder.mkdir()
            got = measure(n, folder)
            row = [str(n)]
            for c in COMMANDS:
                code, seconds, peak, _ = got.get(c, (None, math.nan, math.nan, []))
                row.append("not run" if c not in got else f"{seconds:.1f} s, {peak:.0f} MiB"
                           + ("" if code == 0 else f" (exit {code})"))
                cpu[c].append(seconds if code == 0 else None)
            rows.append(row)
        folder = Path(tmp) / "decimal"
        folder.mkdir()
        dec = measure(7, folder, decimal=True, commands=("init", "check"))
        ex = measure(7, folder, exact_rpy=True, commands=("init", "check"))
    fits = {c: exponent(sizes, cpu[c]) for c in COMMANDS}
    blocks = [table(["joints", *COMMANDS], rows),
              "Growth (CPU ~ n^p, fitted from 8 joints on): "
              + ", ".join(f"{c} n^{p:.1f}" for c, p in fits.items()),
              table(["7-joint chain, frames written as", "init", "check"],
                    [["rpy=\"1.5708 0 -0.7854\"", *(f"{dec[c][1]:.1f} s, {dec[c][2]:.0f} MiB" for c in ("init", "check"))],
                     ["pi/2, -pi/4 to 17 digits", *(f"{ex[c][1]:.1f} s, {ex[c][2]:.0f} MiB" for c in ("init", "check"))]])]
    goals = [Goal(f"{c} grows no faster than n^{GOAL_EXPONENT:.0f} from 8 joints on", fits[c] <= GOAL_EXPONENT,
                  f"n^{fits[c]:.1f}") for c in COMMANDS]
    goals.append(Goal("every command of every chain exits 0", all(v is not None for c in COMMANDS for v in cpu[c]),
                      f"{sum(v is None for c in COMMANDS for v in cpu[c])} failed"))
    ratio = dec["init"][1] / max(ex["init"][1], 1e-9)
    goals.append(Goal("a 7-joint chain in 4-digit decimals costs within 2x of the same in 17 digits (init)",
                      ratio <= 2.0, f"{ratio:.2f}x"))
    return Section(TITLE, tuple(blocks), tuple(goals))


if __name__ == "__main__":
    args = tuple(int(a) for a in sys.argv[1:]) or SIZES
    print(run(args).markdown())
