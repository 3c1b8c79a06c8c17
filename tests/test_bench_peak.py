"""benchmarks/peak.py, the launcher through which the corpus benchmark measures a command: the
peak memory it reports is the command's own, not the (large) benchmark process's that started
it (Linux folds the exec-ing process's high-water mark into the new program's ru_maxrss)."""
from __future__ import annotations

import sys
from pathlib import Path

from benchmarks.corpus import run_command

MIB = 2 ** 20


def test_a_commands_peak_is_its_own_not_its_parents(tmp_path: Path) -> None:
    ballast = bytearray(400 * MIB)
    ballast[::4096] = b"x" * len(ballast[::4096])   # resident: 400 MiB in this process
    code, _, peak, _, cpu = run_command(["/bin/true"], tmp_path, 60)
    assert code == 0 and cpu is not None
    assert peak < 100, peak   # was >= 400 MiB when the benchmark process started the command itself
    code, _, peak, _, _ = run_command([sys.executable, "-c", "b = bytearray(200 * 2 ** 20); b[::4096] = b'x' * len(b[::4096])"],
                                      tmp_path, 60)
    assert code == 0 and 200 <= peak < 300, peak   # the command's own 200 MiB counted
    del ballast


def test_exit_code_stderr_and_timeout(tmp_path: Path) -> None:
    code, _, _, text, _ = run_command([sys.executable, "-c", "import sys; sys.stderr.write('said'); sys.exit(3)"],
                                      tmp_path, 60)
    assert (code, text) == (3, "said")
    code, wall, _, _, _ = run_command(["sleep", "30"], tmp_path, 0.5)
    assert code is None and wall < 20   # killed at the timeout
