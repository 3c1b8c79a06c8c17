"""The exception hierarchy of derive.

Every error a user can cause derives from :class:`DeriveError`; the CLI turns
it into one message and exit code 2. Each subclass also derives from the
builtin that fits, so callers may catch ``ValueError`` or ``OSError``.
"""
from __future__ import annotations

from dataclasses import dataclass


class DeriveError(Exception):
    """Base class of every error derive reports to a user."""


@dataclass(frozen=True)
class Problem:
    """One problem with an input: the field, what was expected, what was given."""

    field: str
    expected: str
    given: str

    def __str__(self) -> str:
        return f"{self.field}: expected {self.expected}, got {self.given}"


class SpecError(DeriveError, ValueError):
    """An arm file (or arm mapping) that is malformed or physically impossible.

    ``problems`` holds every problem found; the message lists them all, after
    ``title`` (e.g. "no such arm" for a file that does not exist).
    """

    def __init__(self, source: str, problems: list[Problem] | tuple[Problem, ...],
                 title: str = "invalid arm description"):
        self.source = source
        self.problems = tuple(problems)
        lines = [f"{title} {source} ({len(self.problems)} problem"
                 f"{'' if len(self.problems) == 1 else 's'}):"]
        lines += [f"  - {p}" for p in self.problems]
        super().__init__("\n".join(lines))


class DerivationError(DeriveError, ArithmeticError):
    """A derivation step that cannot be carried out (e.g. a singular matrix)."""


class CoverageError(DeriveError, ValueError):
    """A kernel output depends on symbols that no input port provides."""


class DataError(DeriveError, ValueError):
    """A measured log, an excitation request or an estimate that cannot be used
    (derive identify, derive excite): the message names the row, column or limit."""


class EmitError(DeriveError, OSError):
    """The output folder cannot be written as asked."""
