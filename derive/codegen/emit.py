"""The one writer: a {relative path: text} mapping becomes files in a folder, as one set.

derive owns exactly the files listed in the folder's ``MANIFEST.json`` (its
``files``, and the manifest itself); everything else in the folder (a CMake
build folder, the user's notes, ``sim/`` of ``derive simulate``) is the user's
and is never moved, changed or deleted. Regenerating replaces derive's previous
files by the new set:

1. every new file is written into a hidden staging folder beside the target;
2. a new path taken by a file derive did not write is a conflict: nothing is
   written and the error names the paths (refusing, rather than overwriting);
3. the manifest is first replaced by one listing old and new paths (so that an
   interrupted run never leaves derive's files unlisted), the previous files
   are moved aside, the new ones renamed into place, then the new manifest;
4. any error (or Ctrl-C) on the way moves everything back: the folder is as it
   was; a kill -9 in the middle of the renames may leave a mix of old and new
   derive files, all listed, which the next run replaces.

A folder that does not exist is created by renaming the staging folder (one
rename). A non-empty folder without a manifest is refused: derive cannot tell
its files from the user's. Folders and files get the permissions of the
user's umask. This module imports the standard library and ``derive.errors``
only.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from derive import jsonio
from derive.errors import EmitError

MANIFEST = "MANIFEST.json"


@dataclass(frozen=True)
class Written:
    """What a write did: the files written, derive's previous files it removed, and the
    top-most entries it kept because derive did not write them (relative POSIX paths)."""

    files: tuple[str, ...]
    removed: tuple[str, ...]
    kept: tuple[str, ...]


def umask() -> int:
    """The process's file-creation mask (read by setting and restoring it)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _check_target(target: Path) -> None:
    if target.is_symlink():
        raise EmitError(f"output folder {target}: expected a folder, got a symbolic link "
                        f"(to {os.readlink(target)}); remove it or choose another --out")
    if target.exists() and not target.is_dir():
        raise EmitError(f"output folder {target}: expected a folder, got a file")
    if target.is_dir() and any(target.iterdir()) and not (target / MANIFEST).is_file():
        raise EmitError(f"output folder {target}: expected an empty folder or one derive wrote "
                        f"(with {MANIFEST}), got a folder with other files; refusing to replace it")


def _safe(rel: str, where: str) -> str:
    """A relative POSIX path inside the folder, or an EmitError naming ``where``."""
    if not rel or rel.startswith("/") or "\\" in rel or any(part in ("", ".", "..") for part in rel.split("/")):
        raise EmitError(f"{where}: expected relative paths inside the folder, got {rel!r}")
    return rel


def listed(text: str) -> set[str] | None:
    """The paths a manifest claims (its ``files``, an object or a list, and itself),
    or None when it is not such a manifest."""
    try:
        doc = jsonio.loads(text)
    except (ValueError, RecursionError):
        return None
    files = doc.get("files") if isinstance(doc, dict) else None
    if not isinstance(files, (dict, list)) or not all(isinstance(x, str) for x in files):
        return None
    return set(files) | {MANIFEST}


def _previous(target: Path) -> set[str]:
    """derive's files in ``target``: what its manifest lists (none without a manifest)."""
    where = target / MANIFEST
    if not where.is_file():
        return set()
    try:
        paths = listed(where.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        paths = None
    if paths is None:
        raise EmitError(f"{where}: expected a JSON object whose \"files\" lists the files derive wrote, got "
                        "something else; derive cannot tell its files from yours (move the folder away)")
    return {_safe(p, str(where)) for p in paths}


def _conflicts(target: Path, new: Iterable[str], ours: set[str]) -> list[str]:
    """New paths (or their folders) taken by something derive did not write, or reached
    through a symbolic link."""
    found = []
    for rel in sorted(new):
        parts = rel.split("/")
        for k in range(1, len(parts) + 1):
            sub = "/".join(parts[:k])
            path = target / sub
            if path.is_symlink():
                found.append(f"{sub} (a symbolic link)")
                break
            if not path.exists():
                break
            if k < len(parts) and not path.is_dir():
                found.append(f"{sub} (a file where derive needs a folder)")
                break
            if k == len(parts) and (sub not in ours or path.is_dir()):
                found.append(sub + ("/ (a folder)" if path.is_dir() else ""))
    return found


def _kept(target: Path, ours: set[str]) -> tuple[str, ...]:
    """The top-most entries of ``target`` that derive did not write."""
    prefixes = {"/".join(p.split("/")[:k]) for p in ours for k in range(1, p.count("/") + 1)}
    out, stack = [], [""]
    while stack:
        base = stack.pop()
        for entry in sorted((target / base).iterdir() if base else target.iterdir()):
            rel = f"{base}/{entry.name}" if base else entry.name
            if rel in ours:
                continue
            if rel in prefixes and entry.is_dir() and not entry.is_symlink():
                stack.append(rel)
            else:
                out.append(rel + ("/" if entry.is_dir() and not entry.is_symlink() else ""))
    return tuple(sorted(out))


def _stage(staging: Path, files: dict[str, str], binary: dict[str, bytes]) -> None:
    for rel, text in sorted(files.items()):
        path = staging / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
    for rel, data in sorted(binary.items()):
        path = staging / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "wb") as handle:
            handle.write(data)


class _Swap:
    """The renames of one regeneration, undone in reverse order on failure."""

    def __init__(self, target: Path) -> None:
        self.target = target
        self.undo: list[tuple[Path, Path]] = []       # rename the first back to the second
        self.made: list[Path] = []                    # folders created in target

    def move(self, src: Path, dst: Path) -> None:
        missing = []
        folder = dst.parent
        while not folder.exists():
            missing.append(folder)
            folder = folder.parent
        for f in reversed(missing):
            f.mkdir()
            self.made.append(f)
        os.rename(src, dst)
        self.undo.append((dst, src))

    def rollback(self) -> None:
        for dst, src in reversed(self.undo):
            try:
                src.parent.mkdir(parents=True, exist_ok=True)
                os.replace(dst, src)
            except OSError:
                pass
        for f in reversed(self.made):
            try:
                f.rmdir()
            except OSError:
                pass


def _inside(target: Path, rel: str) -> bool:
    """Every folder on the way to ``rel`` is a real folder of ``target`` (no symbolic link)."""
    folder = target
    for part in rel.split("/")[:-1]:
        folder = folder / part
        if folder.is_symlink() or not folder.is_dir():
            return False
    return True


def write_tree(target: Path, files: dict[str, str], binary: dict[str, bytes] | None = None) -> Written:
    """Write ``files`` (text) and ``binary`` (relative POSIX paths) into folder ``target``
    as one set, replacing the files derive wrote there before and keeping every other
    entry (see the module docstring).

    ``files`` must hold ``MANIFEST.json`` whose ``files`` lists every other path
    written (ValueError otherwise: a caller's mistake). Raises EmitError when the
    folder cannot be inspected or written, is not a folder derive may write, or a
    new path is taken by a file derive did not write (nothing is written then).
    """
    target = Path(target)
    binary = dict(binary or {})
    new = {_safe(rel, "write_tree") for rel in (*files, *binary)}
    if MANIFEST not in files or listed(files[MANIFEST]) != new:
        raise ValueError(f"write_tree: the new {MANIFEST} must list exactly the other files written")
    try:
        _check_target(target)
        exists = target.is_dir()
        ours = _previous(target) if exists else set()
        conflicts = _conflicts(target, new, ours) if exists else []
    except OSError as exc:  # an ancestor we may not search, a name too long, ...
        raise EmitError(f"output folder {target}: cannot inspect it ({exc.strerror or exc})") from None
    if conflicts:
        raise EmitError(f"output folder {target}: derive did not write {', '.join(conflicts)} "
                        f"(not in {MANIFEST}) and will not replace it; move it away or choose another --out")
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=parent))
    except OSError as exc:
        raise EmitError(f"output folder {target}: cannot write in {parent} ({exc.strerror})") from None
    mask = umask()
    fresh, aside = staging / "new", staging / "previous"
    swap = _Swap(target)
    try:
        _stage(fresh, files, binary)
        if not exists:
            os.chmod(fresh, 0o777 & ~mask)
            os.rename(fresh, target)
            return Written(tuple(sorted(new)), (), ())
        old = sorted(p for p in ours - {MANIFEST} if _inside(target, p)
                     and ((target / p).is_file() or (target / p).is_symlink()))
        # 1. a manifest listing old and new paths: an interrupted run leaves nothing of derive's unlisted
        union = jsonio.dumps({"_note": "derive was interrupted while writing this folder; regenerate",
                              "files": sorted((ours | new) - {MANIFEST})}, sort_keys=False)
        (staging / "union.json").write_text(union, encoding="utf-8")
        aside.mkdir()
        if (target / MANIFEST).exists():
            shutil.copyfile(target / MANIFEST, aside / MANIFEST)
            swap.undo.append((aside / MANIFEST, target / MANIFEST))     # put back: the previous manifest
        else:
            swap.undo.append((target / MANIFEST, staging / "union.json"))  # put back: no manifest
        os.replace(staging / "union.json", target / MANIFEST)
        # 2. derive's previous files aside, 3. the new ones in, 4. the new manifest
        for rel in old:
            swap.move(target / rel, aside / rel)
        for rel in sorted(new - {MANIFEST}):
            swap.move(fresh / rel, target / rel)
        os.replace(fresh / MANIFEST, target / MANIFEST)
    except BaseException as exc:
        swap.rollback()
        if isinstance(exc, OSError):
            raise EmitError(f"output folder {target}: write failed ({exc.strerror or exc})") from None
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    removed = tuple(p for p in old if p not in new)
    try:
        _prune(target, removed)
        kept = _kept(target, new)
    except OSError:      # written already: what is left to tidy or to report is not worth an error
        kept = ()
    return Written(tuple(sorted(new)), removed, kept)


def _prune(target: Path, removed: Iterable[str]) -> None:
    """Remove the folders that held only removed files (never one with anything else)."""
    for rel in removed:
        folder = (target / rel).parent
        while folder != target:
            try:
                folder.rmdir()
            except OSError:
                break
            folder = folder.parent


def write_file(path: Path, text: str) -> None:
    """Write one text file atomically (a temporary sibling, then ``os.replace``), with
    the permissions of the umask; an EmitError names the file on failure."""
    path = Path(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
        os.fchmod(fd, 0o666 & ~umask())
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except OSError as exc:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        raise EmitError(f"{path}: cannot write ({exc.strerror or exc})") from None
