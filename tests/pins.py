"""The exact versions of constraints.txt against the installed ones: a test that compares bytes
made under the constraints (the committed generated/) runs only when the packages those bytes
depend on are installed at those versions, and says which differ otherwise (issue 23).

Under ``make test`` and ``make fuzz`` (DERIVE_REQUIRE_PINNED=1: the Makefile installs the
constraints) a difference fails the test instead: there it must run, never skip."""
from __future__ import annotations

import os
from importlib import metadata
from pathlib import Path

import pytest
from packaging.utils import canonicalize_name

CONSTRAINTS = Path(__file__).resolve().parent.parent / "constraints.txt"


def constraints() -> dict[str, str]:
    """{canonical name: version} of constraints.txt."""
    out = {}
    for line in CONSTRAINTS.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            out[canonicalize_name(name)] = version.strip()
    return out


def differing(names) -> list[str]:
    """'<name> <installed> installed, <pinned> in constraints.txt' for each of ``names`` whose
    installed version is not the constraints' (or is missing from either)."""
    pinned = constraints()
    out = []
    for name in names:
        try:
            have = metadata.version(name)
        except metadata.PackageNotFoundError:
            have = "none"
        want = pinned.get(canonicalize_name(name), "none")
        if have != want:
            out.append(f"{name} {have} installed, {want} in constraints.txt")
    return out


def require_pinned(names, what: str) -> None:
    """Skip (fail under DERIVE_REQUIRE_PINNED) unless ``names`` are installed at the constraints'
    versions; ``what``: the bytes compared, for the message."""
    diff = differing(names)
    if not diff:
        return
    message = f"{what} is compared byte for byte only under constraints.txt's versions: " + "; ".join(diff)
    if os.environ.get("DERIVE_REQUIRE_PINNED"):
        pytest.fail(message + " (DERIVE_REQUIRE_PINNED is set: make venv installs the constraints)")
    pytest.skip(message)
