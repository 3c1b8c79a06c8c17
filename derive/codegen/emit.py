"""The one writer: a {relative path: text} mapping becomes a folder, atomically.

The files are written into a temporary sibling folder, then that folder
replaces the target by rename, so a failing or interrupted run leaves the
previous output as it was. Only folders derive wrote (with a MANIFEST.json)
are ever replaced.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from derive.errors import EmitError

MANIFEST = "MANIFEST.json"


def _check_target(target: Path) -> None:
    if target.is_symlink():
        raise EmitError(f"output folder {target}: expected a folder, got a symbolic link "
                        f"(to {os.readlink(target)}); remove it or choose another --out")
    if target.exists() and not target.is_dir():
        raise EmitError(f"output folder {target}: expected a folder, got a file")
    if target.is_dir() and any(target.iterdir()) and not (target / MANIFEST).is_file():
        raise EmitError(f"output folder {target}: expected an empty folder or one derive wrote "
                        f"(with {MANIFEST}), got a folder with other files; refusing to replace it")


def write_tree(target: Path, files: dict[str, str], binary: dict[str, bytes] | None = None,
               keep: tuple[str, ...] = ()) -> None:
    """Replace folder ``target`` by exactly ``files`` (text) and ``binary``
    (relative POSIX paths); subfolders named in ``keep`` survive from the
    previous output (e.g. the simulation results beside generated code)."""
    target = Path(target)
    try:
        _check_target(target)
    except OSError as exc:  # an ancestor we may not search, a name too long, ...
        raise EmitError(f"output folder {target}: cannot inspect it ({exc.strerror or exc})") from None
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=parent))
    except OSError as exc:
        raise EmitError(f"output folder {target}: cannot write in {parent} ({exc.strerror})") from None
    old = None
    try:
        for rel, text in sorted(files.items()):
            path = staging / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "w", encoding="utf-8", newline="\n") as handle:
                handle.write(text)
        for rel, data in sorted((binary or {}).items()):
            path = staging / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "wb") as handle:
                handle.write(data)
        for sub in keep:
            if (target / sub).is_dir() and not (staging / sub).exists():
                shutil.copytree(target / sub, staging / sub, symlinks=True)
        os.chmod(staging, 0o755)
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old.", dir=parent))
            os.rename(target, old / "x")
        os.rename(staging, target)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        if old is not None and (old / "x").exists() and not target.exists():
            os.rename(old / "x", target)
        raise EmitError(f"output folder {target}: write failed ({exc.strerror or exc})") from None
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
