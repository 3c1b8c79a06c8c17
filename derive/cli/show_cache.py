"""The cache of ``derive show``: what it printed (stdout and stderr) for the same inputs, so that
showing an arm again costs no derivation (issue 23: ``derive show my3`` under 1 s).

Folder: derive.cache.cache_dir(), sub-folder ``show/``. The key is the sha256 of the arm file's
bytes and of every file it reads (derive.cache.read_files: the URDF, the MuJoCo model), of the
arm file's resolved path (messages name it), of the options that change the output (``--at``,
``--latex``, ``--exact``, ``--full``, ``--strict``, stdout's encoding) and of derive itself
(derive.cache.code_fingerprint: its version and the bytes of its code and templates): a changed
input or a new derive is a miss. Only a run that exits 0 is kept; a refusal is never cached.
An entry is strict JSON ({"format", "key", "stdout", "stderr"}); one that cannot be read or holds
another key is ignored and rebuilt. Nothing here imports SymPy: a hit prints and returns.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from derive.cache import cache_dir, code_fingerprint, read_files, write_atomic
from derive.paths import resolve_arm_path

FORMAT = 1


def entry_key(args, encoding: str) -> str | None:
    """The key of ``derive show``'s entry for ``args`` (argparse namespace) printing in ``encoding``;
    None when the arm file cannot be read (the command itself then says why)."""
    path = resolve_arm_path(args.arm)
    files = read_files(path)
    if files is None:
        return None
    h = hashlib.sha256(f"derive show cache {FORMAT}\0{code_fingerprint()}\0".encode())
    options = (str(path.resolve()), args.at, bool(args.latex), bool(args.exact), bool(args.full),
               bool(getattr(args, "strict", False)), encoding)
    h.update(repr(options).encode())
    for name, data in files:
        h.update(f"{name}\0{len(data)}\0".encode())
        h.update(data)
    return h.hexdigest()


def _path(key: str) -> Path:
    return cache_dir() / "show" / f"{key}.json"


def load(key: str) -> tuple[str, str] | None:
    """(stdout, stderr) kept under ``key``, or None."""
    try:
        entry = json.loads(_path(key).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (isinstance(entry, dict) and entry.get("format") == FORMAT and entry.get("key") == key
            and isinstance(entry.get("stdout"), str) and isinstance(entry.get("stderr"), str)):
        return None
    return entry["stdout"], entry["stderr"]


def save(key: str, stdout: str, stderr: str) -> None:
    """Keep (stdout, stderr) under ``key`` (atomically; a folder that cannot be written: nothing)."""
    from derive.jsonio import dumps   # the strict writer (only a miss writes: it may import more)

    write_atomic(_path(key), dumps({"format": FORMAT, "key": key, "stdout": stdout, "stderr": stderr}).encode("utf-8"))
