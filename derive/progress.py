"""Progress bars for the long commands (simulate, sweep, generate, embedded, check).

One place, on tqdm (maintained, the common choice): a bar on standard error
when it is a terminal, nothing at all when it is redirected (a file, a pipe,
CI's log), so that captured output stays clean. Callers::

    from derive.progress import progress
    with progress(total=len(items), desc="sweep", unit="run") as bar:
        for item in items:
            ...
            bar.update()
"""
from __future__ import annotations

import sys
from typing import IO, Any


def progress(total: float | None = None, desc: str = "", unit: str = "it", stream: IO[str] | None = None,
             disable_bar: bool = False, **options: Any):
    """A tqdm bar on ``stream`` (standard error by default), disabled unless the
    stream is a terminal (or when ``disable_bar``). Use it as a context manager
    or call ``close()``; ``update(k)`` advances it."""
    from tqdm import tqdm

    stream = sys.stderr if stream is None else stream
    try:
        shown = stream.isatty()
    except (AttributeError, ValueError):  # a closed or unusual stream: no bar
        shown = False
    return tqdm(total=total, desc=desc, unit=unit, file=stream, disable=disable_bar or not shown,
                dynamic_ncols=True, leave=False, **options)
