"""Benchmarks of derive, run by ``make bench`` (``python -m benchmarks``).

Each section is a module of this package with a ``TITLE`` string and a
``run() -> Section`` function; ``benchmarks.__main__.SECTIONS`` lists the
modules run, in order. A section prints nothing itself: it returns Markdown
tables and goals, which ``__main__`` prints. The helpers here (timing, tables,
goals) are shared by the sections.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

T = TypeVar("T")


@dataclass(frozen=True)
class Goal:
    """A stated target and whether the measurement met it."""

    text: str
    met: bool
    measured: str

    def line(self) -> str:
        """Markdown list item: ``- PASS: text (measured)``."""
        return f"- {'PASS' if self.met else 'MISS'}: {self.text} ({self.measured})"


@dataclass(frozen=True)
class Section:
    """What one benchmark section reports: Markdown blocks (tables, notes) and goals."""

    title: str
    blocks: tuple[str, ...]
    goals: tuple[Goal, ...] = field(default=())

    def markdown(self) -> str:
        """The section as Markdown: heading, blocks, then the goals."""
        return "\n\n".join([f"## {self.title}", *self._parts()]) + "\n"

    def body(self) -> str:
        """The section as Markdown without its heading: blocks, then the goals (what the docs show)."""
        return "\n\n".join(self._parts()) + "\n"

    def _parts(self) -> list[str]:
        goals = ["Goals:\n\n" + "\n".join(g.line() for g in self.goals)] if self.goals else []
        return [*self.blocks, *goals]


def best_of(fn: Callable[[], T], repeat: int = 3) -> tuple[float, T]:
    """Smallest wall time of ``repeat`` calls of ``fn`` (seconds) and the last result."""
    best, result = float("inf"), None
    for _ in range(max(1, repeat)):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result  # type: ignore[return-value]


def table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table; the first column is left-aligned, the others right-aligned. A ``|`` in a cell is
    escaped (``\\|``): unescaped, it would split the cell and break the table (``||W||_2``)."""
    cells = [[_cell(h) for h in headers]] + [[_cell(c) for c in row] for row in rows]
    widths = [max(3, *(len(r[i]) for r in cells)) for i in range(len(headers))]

    def line(row: Sequence[str]) -> str:
        return "| " + " | ".join(c.ljust(w) if i == 0 else c.rjust(w)
                                 for i, (c, w) in enumerate(zip(row, widths))) + " |"

    rule = "| " + " | ".join(("-" * w if i == 0 else "-" * (w - 1) + ":")
                             for i, w in enumerate(widths)) + " |"
    return "\n".join([line(cells[0]), rule] + [line(r) for r in cells[1:]])


def _cell(value: object) -> str:
    return str(value).replace("|", "\\|")


def seconds(t: float) -> str:
    """A duration for a table: milliseconds below 1 s, else seconds."""
    return f"{t * 1e3:.1f} ms" if t < 1 else f"{t:.2f} s"
