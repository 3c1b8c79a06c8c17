"""``derive embedded``: the generated controller on two emulated Cortex-M boards.

For each target and C real type the arm's controller is generated into a
temporary folder (``derive.codegen.files.generate_files``), cross-compiled with
``arm-none-eabi-gcc`` together with its self-test and the board support in
``derive/embedded/board/`` (vector table, reset and fault handlers, linker script), and run
on QEMU's MPS2 boards through semihosting:

* ``m4f``: Cortex-M4F with its single-precision FPU (``mps2-an386``), float;
* ``m3``:  Cortex-M3 without FPU (``mps2-an385``), double and float.

Reported per configuration: the self-test's ``N passed, N failed``; flash
(text + data) and RAM (data + bss) of the controller's two objects
(``arm-none-eabi-size``) and the flash it pulls in from libm and libgcc (link
map of ``board/footprint.c``); stack: the largest frame of any controller
function (``-fstack-usage``), the deepest call chain inside the controller
(``-fcallgraph-info``; libm and libgcc frames not known there) and the
high-water mark measured on the board (``board/measure.c``); executed
instructions per call of ``npid_step``, ``dobc_step`` and ``gains``, counted
with QEMU's ``-icount shift=0`` and SysTick. They are instructions, not
cycles: QEMU does not model pipeline, memory wait states or FPU latency.

Exit code 0 only when every self-test passed; 1 otherwise; 2 (a clear
message, never a traceback) when the toolchain or ``derive/embedded/board/`` is missing or
the generated code does not compile.
"""
from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from derive.errors import DeriveError

EMBEDDED_DIR = Path(__file__).resolve().parent / "board"
INSTALL_HINT = ("install them with `bash scripts/install-system-deps.sh` (Debian packages "
                "gcc-arm-none-eabi, libnewlib-arm-none-eabi, qemu-system-arm)")
STRICT = ("-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror")
OPTIMISE = ("-O2", "-ffunction-sections", "-fdata-sections")
LINK = ("--specs=rdimon.specs", "-nostartfiles", "-Wl,--gc-sections")
TIMEOUT = 120  # seconds per QEMU run; the slowest (M3, double) takes about one
FUNCTIONS = ("npid_step", "dobc_step", "gains")


class EmbeddedError(DeriveError, RuntimeError):
    """The cross toolchain, QEMU or the board files are missing, or a build failed."""


@dataclass(frozen=True)
class Target:
    """One emulated board and the compiler flags of its core."""

    name: str
    core: str
    machine: str
    flags: tuple[str, ...]
    reals: tuple[str, ...]


# -ffp-contract=fast lets the M4F's FPU fuse a*b + c into one VFMA (one rounding
# instead of two: inside the stated float bound, checked by the self-test on the board).
TARGETS = (
    Target("m4f", "Cortex-M4F", "mps2-an386",
           ("-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-ffp-contract=fast"),
           ("float",)),
    Target("m3", "Cortex-M3", "mps2-an385", ("-mcpu=cortex-m3", "-mthumb", "-mfloat-abi=soft"),
           ("double", "float")),
)


@dataclass
class Result:
    """Everything measured for one (target, real) configuration."""

    target: Target
    real: str
    passed: int = 0
    failed: int = 0
    problem: str = ""                  # a fault, a time-out, a missing summary line
    output: str = ""
    flash: int = 0                     # controller objects: text + data
    ram: int = 0                       # controller objects: data + bss
    lib_flash: int = 0                 # pulled in from libm and libgcc
    frame: tuple[str, int] = ("", 0)   # largest single frame (-fstack-usage)
    chain: int = 0                     # deepest chain inside the controller
    stack: int = 0                     # measured on the board, angles within +-2.93 rad
    stack_far: int = 0                 # measured, angles near 3e4 rad (libm's big reduction)
    insns: dict[str, tuple[float, float]] = field(default_factory=dict)  # mean, max per call

    @property
    def ok(self) -> bool:
        return not self.problem and self.failed == 0 and self.passed > 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI: derive embedded [ARM] [--target m4f|m3|all] [--keep DIR]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--target", choices=[t.name for t in TARGETS] + ["all"], default="all",
                        help="which board to run (default: all)")
    parser.add_argument("--keep", metavar="DIR", default=None,
                        help="build in DIR and keep the sources, objects, ELF files and maps")


def check_toolchain() -> None:
    """Raise EmbeddedError naming whatever is missing to build and run."""
    missing = [tool for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size", "qemu-system-arm")
               if shutil.which(tool) is None]
    if not missing:
        specs = _run(["arm-none-eabi-gcc", "-print-file-name=rdimon.specs"]).stdout.strip()
        if not Path(specs).is_file():
            missing.append("newlib's rdimon.specs")
    if missing:
        raise EmbeddedError(f"derive embedded needs {', '.join(missing)}: {INSTALL_HINT}")
    absent = [name for name in ("startup.c", "mps2.ld", "measure.c", "footprint.c")
              if not (EMBEDDED_DIR / name).is_file()]
    if absent:
        raise EmbeddedError(f"board support missing: {', '.join(absent)} not found in {EMBEDDED_DIR} "
                            "(derive embedded runs from a checkout of the repository)")


def _run(cmd: list[str], cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                              stdin=subprocess.DEVNULL)
    except OSError as exc:
        raise EmbeddedError(f"cannot run {cmd[0]}: {exc.strerror or exc}") from None
    except subprocess.TimeoutExpired:
        raise EmbeddedError(f"{' '.join(cmd)}: no answer after {timeout:.0f} s") from None


def cc(target: Target, args: list[str], cwd: Path) -> None:
    """Run arm-none-eabi-gcc with the target's flags (compiling and linking alike) in ``cwd``."""
    cmd = ["arm-none-eabi-gcc", *target.flags, *args]
    proc = _run(cmd, cwd)
    if proc.returncode != 0:
        raise EmbeddedError(f"{target.core} build failed:\n  {' '.join(cmd)}\n{proc.stderr.rstrip()}")


def build(target: Target, c_dir: Path, arm: str, out: Path) -> None:
    """Objects (with .su and .ci), then selftest.elf, measure.elf and footprint.elf in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    inc = [f"-I{c_dir}", f"-DARM={arm}", f'-DARM_HEADER="{arm}.h"']
    for stem in (arm, f"{arm}_kernels"):
        cc(target, [*STRICT, *OPTIMISE, "-fstack-usage", "-fcallgraph-info=su", "-c",
                     str(c_dir / f"{stem}.c"), "-o", f"{stem}.o"], out)
    cc(target, [*STRICT, *OPTIMISE, "-c", str(c_dir / f"{arm}_selftest.c"), "-o", "selftest.o"], out)
    for name in ("startup", "measure", "footprint"):
        cc(target, ["-std=c99", "-Wall", "-Wextra", "-Werror", *OPTIMISE, *inc, "-c",
                     str(EMBEDDED_DIR / f"{name}.c"), "-o", f"{name}.o"], out)
    lib = [f"{arm}.o", f"{arm}_kernels.o", "startup.o"]
    for main in ("selftest", "measure", "footprint"):
        cc(target, [*LINK, f"-T{EMBEDDED_DIR / 'mps2.ld'}", f"-Wl,-Map={main}.map", "-o", f"{main}.elf",
                     f"{main}.o", *lib, "-lm"], out)


def run_qemu(target: Target, elf: Path, icount: bool = False, timeout: float = TIMEOUT) -> tuple[int, str]:
    """Run ``elf`` on the target's board; (exit status, output). 124 or 137: timed out."""
    cmd = ["timeout", "-k", "5", str(timeout), "qemu-system-arm", "-M", target.machine, "-nographic",
           "-semihosting-config", "enable=on,target=native", *(["-icount", "shift=0"] if icount else []),
           "-kernel", str(elf)]
    proc = _run(cmd, timeout=timeout + 30)
    return proc.returncode, proc.stdout + proc.stderr


def parse_summary(output: str) -> tuple[int, int] | None:
    """The self-test's closing ``N passed, N failed`` line, if any."""
    found = re.findall(r"^(\d+) passed, (\d+) failed\s*$", output, re.M)
    return (int(found[-1][0]), int(found[-1][1])) if found else None


def object_sizes(objects: list[Path]) -> tuple[int, int]:
    """(flash, RAM) of objects: text + data and data + bss, from arm-none-eabi-size."""
    proc = _run(["arm-none-eabi-size", *map(str, objects)])
    flash = ram = 0
    for line in proc.stdout.splitlines()[1:]:
        text, data, bss = (int(v) for v in line.split()[:3])
        flash, ram = flash + text + data, ram + data + bss
    return flash, ram


def library_flash(map_file: Path) -> int:
    """Bytes of code and data that a link map shows taken from libm.a and libgcc.a."""
    text = map_file.read_text(errors="replace")
    text = text[text.find("Linker script and memory map"):]
    pattern = r"^ (\.(?:text|rodata|data|ARM)\S*)\s+0x([0-9a-f]+)\s+0x([0-9a-f]+) (\S+)$"
    return sum(int(size, 16) for _name, _addr, size, src in re.findall(pattern, text, re.M)
               if re.search(r"/lib(m|gcc)\.a\(", src))


def stack_frames(out: Path) -> dict[str, int]:
    """Frame bytes of every controller function, from the -fstack-usage files."""
    frames = {}
    for su in sorted(out.glob("*.su")):
        for line in su.read_text().splitlines():
            where, size, _kind = line.rsplit("\t", 2)
            frames[where.rsplit(":", 1)[-1]] = int(size)
    return frames


def call_chain(out: Path, frames: dict[str, int]) -> int:
    """Deepest sum of frames along a call chain through controller functions (.ci graphs)."""
    calls: dict[str, set[str]] = {}
    for ci in out.glob("*.ci"):
        for src, dst in re.findall(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"', ci.read_text()):
            calls.setdefault(src.rsplit(":", 1)[-1], set()).add(dst.rsplit(":", 1)[-1])

    def depth(name: str, seen: frozenset[str]) -> int:
        below = [depth(c, seen | {c}) for c in calls.get(name, ()) if c in frames and c not in seen]
        return frames[name] + max(below, default=0)

    return max((depth(name, frozenset({name})) for name in frames), default=0)


def parse_measure(output: str) -> tuple[dict[str, tuple[float, float]], tuple[int, int], str]:
    """From measure.elf's output: instructions per call (mean and max over the inputs) of
    each function, the measured stack (usual angles, far angles), and a problem if any."""
    cal = re.search(r"^calibrate insns=(\d+) ticks=(\d+)", output, re.M)
    done = re.search(r"^measure done codes=(\d+)", output, re.M)
    stacks = [(int(b), int(f)) for b, f in re.findall(r"^stack \w+ bytes=(\d+) far=(\d+)", output, re.M)]
    per_call: dict[str, list[float]] = {}
    if cal and int(cal.group(2)) > 0:
        per_tick = int(cal.group(1)) / int(cal.group(2))
        for name, n, t, b in re.findall(r"^time (\w+) input=\d+ calls=(\d+) ticks=(\d+) baseline=(\d+)",
                                        output, re.M):
            per_call.setdefault(name, []).append((int(t) - int(b)) * per_tick / int(n))
    if not done or set(per_call) != set(FUNCTIONS) or len(stacks) != len(FUNCTIONS):
        return {}, (0, 0), "measurement incomplete:\n" + output
    insns = {name: (sum(v) / len(v), max(v)) for name, v in per_call.items()}
    problem = "a call returned an error code while measured" if int(done.group(1)) else ""
    return insns, (max(s[0] for s in stacks), max(s[1] for s in stacks)), problem


def evaluate(target: Target, real: str, c_dir: Path, arm: str, out: Path) -> Result:
    """Build, run the self-test and the measurement, and collect the figures."""
    build(target, c_dir, arm, out)
    r = Result(target, real)
    status, r.output = run_qemu(target, out / "selftest.elf")
    summary = parse_summary(r.output)
    if summary:
        r.passed, r.failed = summary
    if status in (124, 137):
        r.problem = f"self-test timed out after {TIMEOUT} s"
    elif "FAULT:" in r.output:
        r.problem = "fault: " + r.output[r.output.index("FAULT:"):].splitlines()[0]
    elif summary is None:
        r.problem = f"no 'N passed, N failed' line (exit status {status})"
    elif (status != 0) != (r.failed != 0):
        r.problem = f"exit status {status} does not match {r.failed} failed"
    r.flash, r.ram = object_sizes([out / f"{arm}.o", out / f"{arm}_kernels.o"])
    r.lib_flash = library_flash(out / "footprint.map")
    frames = stack_frames(out)
    if frames:
        r.frame = max(frames.items(), key=lambda item: (item[1], item[0]))
        r.chain = call_chain(out, frames)
    status, text = run_qemu(target, out / "measure.elf", icount=True)
    r.insns, (r.stack, r.stack_far), problem = parse_measure(text)
    if status != 0 and not problem:
        problem = f"measurement exited with status {status}: {text.strip()[-300:]}"
    r.problem = r.problem or problem
    return r


def table(arm: str, results: list[Result]) -> str:
    """The Markdown report: one row per (target, real), then what the columns mean."""
    rows = ["| target | real | self-test | flash B | RAM B | libm+libgcc flash B | largest frame B "
            "| chain B | stack used B | npid_step insns | dobc_step insns | gains insns |",
            "|---|---|---|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    for r in results:
        status = f"{r.passed} passed, {r.failed} failed" + (f" ({r.problem.splitlines()[0]})" if r.problem else "")
        name = r.frame[0].removeprefix(f"{arm}_")
        insns = [f"{r.insns[f][0]:.0f} / {r.insns[f][1]:.0f}" if f in r.insns else "-" for f in FUNCTIONS]
        rows.append(f"| {r.target.core} ({r.target.machine}) | {r.real} | {status} | {r.flash} | {r.ram} "
                    f"| {r.lib_flash} | {r.frame[1]} ({name}) | {r.chain} | {r.stack} ({r.stack_far}) "
                    f"| {' | '.join(insns)} |")
    return "\n".join([
        f"Arm `{arm}`, arm-none-eabi-gcc -O2, run on QEMU's MPS2 boards.", "", *rows, "",
        "flash, RAM: the controller's objects (arm-none-eabi-size: text + data, data + bss); "
        "libm+libgcc: what they pull in at link time.",
        "Stack: largest frame of a controller function (-fstack-usage); deepest chain of frames inside "
        "the controller (-fcallgraph-info, without libm and libgcc); used on the board, angles within "
        "+-2.93 rad (and near 3e4 rad, libm's large-argument reduction).",
        "insns: executed instructions per call, mean / max over 16 inputs, counted by QEMU "
        "(-icount shift=0, SysTick); instructions, not cycles.",
    ])


def run(args: argparse.Namespace) -> int:
    """Run every configuration of the chosen targets; print the report; 0 if all passed."""
    from derive.cli import report_warnings
    from derive.codegen.files import generate_files
    from derive.codegen.emit import write_tree
    from derive.codegen.kernels import ParamsMode
    from derive.control.pipeline import derive
    from derive.control.ranges import check_ranges
    from derive.cli import load_cli_arm
    from derive.model.spec import resolve_arm_path
    from derive.progress import progress

    check_toolchain()
    targets = [t for t in TARGETS if args.target in ("all", t.name)]
    arm = load_cli_arm(args)
    d = derive(arm)
    report_warnings(d)
    for real in sorted({r for t in targets for r in t.reals}):
        check_ranges(d, real)  # every real type fits before anything is written or built
    arm_bytes = resolve_arm_path(args.arm).read_bytes()
    keep = Path(args.keep) if args.keep else None
    if keep is not None:
        keep.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="derive-embedded-") as tmp:
        root = keep or Path(tmp)
        sources = {}
        for real in sorted({r for t in targets for r in t.reals}):
            sources[real] = root / f"src-{real}" / arm.name
            write_tree(sources[real], generate_files(d, arm_bytes, real, ParamsMode.BAKED))
        results = []
        configurations = [(t, real) for t in targets for real in t.reals]
        with progress(total=len(configurations), desc="embedded", unit="target") as bar:
            for t, real in configurations:
                bar.set_postfix_str(f"{t.core}, {real}")
                r = evaluate(t, real, sources[real] / "c", arm.name, root / f"{t.name}-{real}")
                if r.problem or r.failed:
                    bar.write(f"derive: {t.core} ({t.machine}), {real}:\n{r.output.rstrip()}\n{r.problem}",
                              file=sys.stderr)
                results.append(r)
                bar.update()
    print(table(arm.name, results))
    ok = all(r.ok for r in results)
    total = (sum(r.passed for r in results), sum(r.failed for r in results))
    print(f"\nembedded: {total[0]} passed, {total[1]} failed"
          + ("" if ok else f" ({sum(not r.ok for r in results)} configuration(s) failed)"))
    return 0 if ok else 1
