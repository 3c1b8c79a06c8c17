"""Run one command and write its own exit code, CPU time and peak memory (benchmarks/corpus.py).

``python -I -S benchmarks/peak.py OUT TIMEOUT COMMAND...`` runs COMMAND (in a session of its
own), kills its session after TIMEOUT seconds, and writes ``<code|None> <user s> <system s>
<peak KiB>`` to OUT: ``os.wait4``'s rusage of the command, which covers its waited-for children.

Why a launcher: Linux carries the high-water mark of the memory a process had when it called
exec into the new program's ``ru_maxrss`` (fork copies the parent's memory, exec folds its
peak in; vfork and posix_spawn share it), so every command started from the benchmark
process reported at least that process's own size: 514 MiB for a refused ``init`` once the
earlier sections had loaded SymPy, CasADi and Pinocchio. Started from this launcher (a few MiB:
no site packages, nothing imported beyond os, signal, sys, time), a command's peak is its own.
"""
import os
import signal
import sys
import time


def main(out: str, timeout: str, *argv: str) -> None:
    start = time.monotonic()
    pid = os.fork()
    if pid == 0:   # the command: a session of its own, so that a timeout kills what it started too
        try:
            os.setsid()
            os.execvp(argv[0], argv)
        finally:
            os._exit(127)
    code = None
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
            break
        if time.monotonic() - start > float(timeout):
            os.killpg(pid, signal.SIGKILL)
            _, _, usage = os.wait4(pid, 0)
            break
        time.sleep(0.05)
    with open(out, "w") as f:
        f.write(f"{code} {usage.ru_utime!r} {usage.ru_stime!r} {usage.ru_maxrss}\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
