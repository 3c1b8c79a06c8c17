"""Run every benchmark section in turn and print Markdown: ``python -m benchmarks``.

To add a section, write ``benchmarks/<name>.py`` with ``TITLE`` and
``run() -> Section`` and list ``"<name>"`` in :data:`SECTIONS`. Goals print as
PASS/MISS and do not change the exit status (timings on a shared machine are
noisy); a section that finds a wrong result raises, and the run fails.
"""
from __future__ import annotations

import importlib
import platform
import sys
import time

SECTIONS: tuple[str, ...] = ("dynamics", "codegen", "simulation", "mujoco", "observer", "spatial", "identify", "payload",
                             "scaling", "corpus")


def main(names: tuple[str, ...] = SECTIONS) -> int:
    """Run the sections ``names`` (modules of this package), printing each as it finishes."""
    import sympy

    print(f"# derive benchmarks\n\nPython {platform.python_version()}, SymPy {sympy.__version__}, "
          f"{platform.machine()}\n", flush=True)
    misses = 0
    for name in names:
        module = importlib.import_module(f"{__package__}.{name}")
        start = time.perf_counter()
        section = module.run()
        print(section.markdown(), flush=True)
        print(f"_{module.TITLE}: {time.perf_counter() - start:.1f} s_\n", flush=True)
        misses += sum(not g.met for g in section.goals)
    print(f"{misses} goal(s) missed." if misses else "All goals met.")
    return 0


if __name__ == "__main__":
    sys.exit(main(tuple(sys.argv[1:]) or SECTIONS))
