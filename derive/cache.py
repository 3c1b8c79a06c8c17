"""The user's cache folder, derive's fingerprint, and the files an arm file reads: what every
cache of derive keys its entries by (``derive simulate``'s: derive.sim.cache; ``derive show``'s:
derive.cli.show_cache). Light on purpose (the standard library and platformdirs): a cache hit
needs nothing heavier.

Folder: ``$DERIVE_CACHE_DIR`` when set, else platformdirs' ``user_cache_dir("derive")``
(``~/.cache/derive`` on Linux). Entries are written atomically (a temporary file in the same
folder, then ``os.replace``): a reader sees a whole entry or none.
"""
from __future__ import annotations

import functools
import hashlib
import os
import tempfile
import tomllib
from pathlib import Path

from derive.paths import PACKAGE, TEMPLATES

ENV = "DERIVE_CACHE_DIR"


def cache_dir() -> Path:
    """The folder of the cache: ``$DERIVE_CACHE_DIR``, else ``user_cache_dir("derive")``."""
    if os.environ.get(ENV):
        return Path(os.environ[ENV])
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("derive"))


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """derive's version and the sha256 of its code and templates (every file of the package
    and of the templates folder, by relative path): a new derive, released or edited, never
    reads an old entry."""
    from derive.version import __version__

    h = hashlib.sha256(f"derive {__version__}\0".encode())
    for root in (PACKAGE, TEMPLATES):
        for p in code_files(root):
            h.update(f"{root.name}/{p.relative_to(root).as_posix()}\0".encode())
            h.update(hashlib.sha256(p.read_bytes()).digest())
    return h.hexdigest()


def code_files(root: Path) -> list[Path]:
    """The files under ``root`` that :func:`code_fingerprint` hashes, in its order: those of
    ``sorted(root.rglob("*"))`` that are files, outside ``__pycache__`` and not .pyc or .so. Listed by
    os.walk without entering ``__pycache__`` (rglob stats every bytecode file there: 4 of the 8 ms)."""
    found = []
    for folder, subfolders, names in os.walk(root):
        subfolders[:] = [x for x in subfolders if x != "__pycache__"]
        found += [Path(folder, name) for name in names]
    return [p for p in sorted(found) if p.is_file() and p.suffix not in (".pyc", ".so")]


def read_files(source: Path) -> list[tuple[str, bytes]] | None:
    """The arm file's bytes and those of every file it reads (``[arm] urdf``, ``[arm] mjcf`` and the
    files it includes, ``[simulation] mujoco_model``; a missing one as b"missing"); None when the arm
    file cannot be read."""
    try:
        raw = Path(source).read_bytes()
    except OSError:
        return None
    out = [("arm", raw)]
    try:
        data = tomllib.loads(raw.decode("utf-8", errors="replace"))
    except tomllib.TOMLDecodeError:
        return out
    for table, key in (("arm", "urdf"), ("arm", "mjcf"), ("simulation", "mujoco_model")):
        name = data.get(table, {}).get(key) if isinstance(data.get(table), dict) else None
        if isinstance(name, str) and name:
            try:
                out.append((f"{table}.{key}", (Path(source).parent / name).read_bytes()))
            except OSError:
                out.append((f"{table}.{key}", b"missing"))
            out += _included(Path(source).parent, name, f"{table}.{key}")
    return out


def _included(folder: Path, name: str, field: str) -> list[tuple[str, bytes]]:
    """The bytes of the files an MJCF's <include> elements read (none for a URDF or a broken file)."""
    from derive.model.fields import Reader
    from derive.model.mjcf_xml import expanded_tree

    if not name.endswith(".xml"):
        return []
    _, files = expanded_tree(Reader(), field, name, folder, "")
    out = []
    for path in files[1:]:
        try:
            out.append((f"{field} <include> {path.name}", path.read_bytes()))
        except OSError:
            out.append((f"{field} <include> {path.name}", b"missing"))
    return out


def write_atomic(path: Path, data: bytes) -> bool:
    """``data`` to ``path`` through a temporary file in its folder and os.replace; whether it was
    written. An error leaves no temporary file and is not raised (a cache that cannot write is
    only slower)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    except OSError:
        return False
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
        return True
    except OSError:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        return False
