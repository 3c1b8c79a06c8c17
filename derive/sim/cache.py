"""The cache of ``derive simulate``: the derivation, the compiled closed loop
(derive.sim.compiled.LoopBuild), the sample-time check of the forms run, and the figures,
kept between runs in the user's cache folder (issue 23).

Folder: ``$DERIVE_CACHE_DIR`` when set, else platformdirs' ``user_cache_dir("derive")``
(``~/.cache/derive`` on Linux), sub-folder ``simulate/``. One entry per key
(:func:`entry_key`): the sha256 of the arm file's bytes, of every file it reads (the URDF of
``[arm] urdf``, the ``[simulation] mujoco_model``), of the motors and ``[simulation]`` as the
command line left them (``--voltage-limits``, ``--reference-from-pose``), of the options that
change the derivation or the loop (observer step, plants, MuJoCo friction), and of derive
itself: its version and the bytes of its code and templates (:func:`code_fingerprint`), so a
new derive, released or edited, never reads an old entry. A figure is kept under the sha256
of everything it is drawn from (:meth:`SimCache.figure`: the traces' bytes, the figure's
arguments, derive's fingerprint and matplotlib's version), so a run whose traces are the
same bytes gets the same PNG without drawing it again.

Entries are pickles written atomically (a temporary file in the same folder, then
``os.replace``): a reader sees a whole entry or none. An entry that cannot be read, is cut
short, or holds another key or format is ignored and rebuilt. The runs themselves are not
cached: every ``derive simulate`` integrates the plant and computes its metrics anew.
"""
from __future__ import annotations

import hashlib
import io
import pickle
from pathlib import Path
from typing import Callable, TypeVar

import numpy as np

from derive.cache import ENV, cache_dir, code_fingerprint, read_files, write_atomic as _write_atomic

__all__ = ["ENV", "SimCache", "cache_dir", "code_fingerprint", "entry_key"]

FORMAT = 1          # the layout of an entry; a change makes every old entry a miss
T = TypeVar("T")


def _read_files(arm) -> list[tuple[str, bytes]]:
    """The arm file's bytes and those of every file it reads (derive.cache.read_files); an arm not
    from a file: its description (repr) instead."""
    return read_files(Path(arm.source)) or [("arm", repr(arm).encode())]


def entry_key(arm, options: dict[str, object]) -> str:
    """The key of the entry of ``arm`` (as the command line left it) under ``options`` (module
    docstring): hex sha256."""
    h = hashlib.sha256(f"derive simulate cache {FORMAT}\0{code_fingerprint()}\0".encode())
    for name, data in _read_files(arm):
        h.update(f"{name}\0{len(data)}\0".encode())
        h.update(data)
    h.update(repr(arm.motors).encode())
    h.update(repr(arm.simulation).encode())
    h.update(repr(sorted(options.items())).encode())
    return h.hexdigest()


class SimCache:
    """One entry of the cache (module docstring); ``folder`` None: no cache (``--no-cache``),
    every value made anew and nothing written."""

    def __init__(self, folder: Path | None, key: str = ""):
        self.folder, self.key = folder, key
        self.path = folder / "simulate" / f"{key}.pickle" if folder is not None else None
        self.data: dict = self._read() if self.path is not None else {}
        self.hit = bool(self.data)
        self._dirty = False

    @classmethod
    def open(cls, arm, options: dict[str, object], enabled: bool = True) -> SimCache:
        """The entry of ``arm`` under ``options`` in :func:`cache_dir` (empty when none or
        unreadable); ``enabled`` False: the no-op cache."""
        return cls(cache_dir(), entry_key(arm, options)) if enabled else cls(None)

    def _read(self) -> dict:
        try:
            with open(self.path, "rb") as f:
                entry = pickle.load(f)
        except Exception:   # missing, cut short, corrupt, or from an incompatible derive: a miss
            return {}
        if not (isinstance(entry, dict) and entry.get("format") == FORMAT and entry.get("key") == self.key
                and isinstance(entry.get("values"), dict)):
            return {}
        return entry["values"]

    def get(self, name, make: Callable[[], T]) -> T:
        """The value ``name`` of this entry, made by ``make()`` (and kept) when absent."""
        if name in self.data:
            return self.data[name]
        value = make()
        if self.path is not None:
            self.data[name] = value
            self._dirty = True
        return value

    def save(self) -> None:
        """Write the entry (atomically) when a value was added."""
        if self.path is None or not self._dirty:
            return
        buf = io.BytesIO()
        try:
            pickle.dump({"format": FORMAT, "key": self.key, "values": self.data}, buf,
                        protocol=pickle.HIGHEST_PROTOCOL)
        except (pickle.PicklingError, TypeError, AttributeError, RecursionError):
            return   # a value that does not pickle: no entry (the next run is a miss, not wrong)
        self._dirty = not _write_atomic(self.path, buf.getvalue())

    def figure(self, what: tuple, traces, make: Callable[[], bytes]) -> bytes:
        """The PNG ``make()`` draws from ``traces`` with the arguments ``what``, kept under the
        sha256 of its inputs; a kept file that is not a whole PNG is drawn again."""
        if self.folder is None:
            return make()
        from importlib import metadata

        h = hashlib.sha256(f"{code_fingerprint()}\0matplotlib {metadata.version('matplotlib')}\0"
                           f"{what!r}\0".encode())
        for tr in traces:
            h.update(f"{tr.name}\0{tr.failure!r}\0".encode())
            for a in (tr.t, tr.theta, tr.dtheta, tr.yd, tr.u, tr.error):
                a = np.ascontiguousarray(a)
                h.update(f"{a.dtype.str}{a.shape}".encode())
                h.update(a.tobytes())
        path = self.folder / "figures" / f"{h.hexdigest()}.png"
        try:
            png = path.read_bytes()
            if png.startswith(b"\x89PNG\r\n\x1a\n") and png.endswith(b"IEND\xaeB`\x82"):
                return png
        except OSError:
            pass
        png = make()
        _write_atomic(path, png)
        return png
