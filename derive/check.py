"""``derive check``: the paper's claims as proof obligations (issue 3, in progress)."""
from __future__ import annotations


def add_arguments(parser) -> None:
    from .cli import add_arm_argument

    add_arm_argument(parser)


def run(args) -> int:
    from .errors import DeriveError

    raise DeriveError("derive check is not available yet")
