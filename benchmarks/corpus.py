"""The URDF and MJCF corpora through every command (``make corpus``; a section of ``make bench``).

For every arm of tests/data/urdf/corpus/corpus.toml and tests/data/mjcf/menagerie/corpus.toml
(MuJoCo Menagerie arms: ``derive init`` reads the MJCF, ``simulate`` and ``fmu --plant`` run derive's
plant; tests/test_mujoco_mjcf.py runs MuJoCo on them), in a temporary folder, as a
user would: ``derive init`` (the arm's base, tip and init options; a ``locked``
table written into the arm file after it), ``show``, ``check``, ``generate``,
then the generated C self-tests (controller and plant, built with gcc under the
strict flags of tests/cbuild.py) and the generated Python module's self-check
(its mass matrix J, bias G with damping and gravity against derive's dynamics at 5 seeded states,
and every controller step returning code 0 with finite outputs), ``simulate``
(the starter file's own settings, no ``--force``), ``fmu --plant``, and the stated sample-time limits
beside the true ones (benchmarks/limits_truth.py, in a process of its own: the limits column, and the
goals stated <= true and within 1.5x). Each
command must exit 0 (the limits check: 0, or 3 when a stated limit is above the true one: a goal it
misses, not a failed command), or, for an arm whose file has a real defect, ``init`` must
give the one expected refusal (exit 2, the text of corpus.toml's ``refusal``, no
traceback). Each command runs under a timeout (``CORPUS_TIMEOUT`` seconds,
default 900); wall time and peak resident memory (``os.wait4``'s ru_maxrss of
that command's process, started from the small launcher benchmarks/peak.py) are recorded per arm and command, beside Pinocchio's
load time of the file (buildModelFromUrdf, buildModelFromMJCF). ``python -m benchmarks.corpus [--out DIR] [NAME ...]`` writes
``DIR/corpus.json`` and ``DIR/corpus.md`` (default DIR: build/corpus) and exits
1 when a command failed.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from benchmarks import Goal, Section, table
from benchmarks.corpus_limits import limit_goals, limits_markdown
from derive.jsonio import dumps

TITLE = "URDF and MJCF corpus: every arm through every command"
ROOT = Path(__file__).resolve().parents[1]
TIMEOUT = float(os.environ.get("CORPUS_TIMEOUT", "900"))
PEAK = Path(__file__).resolve().with_name("peak.py")   # the launcher that measures a command
STRICT = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-Wvla", "-O2"]


@dataclass
class Step:
    """One command of one arm: exit status, wall time [s], peak memory [MiB] (None: not
    measured: the C self-tests run several programs), what it said."""

    command: str
    ok: bool
    seconds: float
    peak_mib: float | None
    detail: str = ""
    cpu_seconds: float | None = None   # user + system time of the command's process and its children


@dataclass
class ArmResult:
    name: str
    joints: int | None
    expect: str
    pinocchio_load_s: float | None
    commands: list[Step] = field(default_factory=list)
    tracking: dict | None = None   # the starter file's simulate run: _tracking
    limits: dict | None = None     # benchmarks/limits_truth.py's JSON: stated and true limits per form


Run = tuple[int | None, float, float | None, str, float | None]


def run_command(argv: list[str], cwd: Path, timeout: float) -> Run:
    """(exit code or None on timeout, wall time, peak MiB, the last lines of stderr, CPU time) of
    ``argv``: the CPU time is user + system of the command's process and its waited-for children,
    the figure the goals read (the wall time of a shared machine measures the other loads as much
    as the command); the peak is the command's own, measured through benchmarks/peak.py (a child
    of this process would report at least this process's size)."""
    start = time.perf_counter()
    with tempfile.TemporaryFile() as err, tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, DERIVE_CACHE_DIR=str(Path(cwd) / ".derive-cache"))   # cold, and never the user's
        env.pop("PYTHONDONTWRITEBYTECODE", None)   # Python's bytecode cache on, as for a user (run_corpus primes it)
        report = Path(tmp) / "usage"
        subprocess.run([sys.executable, "-I", "-S", str(PEAK), str(report), repr(timeout), *argv], cwd=cwd, env=env,
                       stdout=subprocess.DEVNULL, stderr=err, check=True)
        code, user, system, kib = report.read_text().split()
        err.seek(0)
        text = err.read().decode("utf-8", "replace")
    wall = time.perf_counter() - start
    return None if code == "None" else int(code), wall, int(kib) / 1024, text, float(user) + float(system)


def _derive(*args: str) -> list[str]:
    return [sys.executable, "-m", "derive", *args]


def _write_locked(arm_file: Path, locked: dict) -> None:
    """Put ``locked = {...}`` under [arm], where the starter file's comment suggests it."""
    text = arm_file.read_text(encoding="utf-8")
    entries = ", ".join(f"{k} = {float(v)!r}" for k, v in locked.items())
    line = next(x for x in text.splitlines() if x.startswith("# locked = "))
    arm_file.write_text(text.replace(line, f"locked = {{ {entries} }}", 1), encoding="utf-8")


def _c_selftests(folder: Path, name: str, timeout: float) -> tuple[bool, str]:
    c = folder / "gen" / name / "c"
    library = [c / f"{name}.c", c / f"{name}_kernels.c", c / f"{name}_plant.c"]
    said = []
    for test in ("selftest", "plant_selftest"):
        exe = folder / f"{name}_{test}"
        build = subprocess.run(["gcc", *STRICT, "-o", str(exe), str(c / f"{name}_{test}.c"), *map(str, library),
                                "-lm"], capture_output=True, text=True, timeout=timeout)
        if build.returncode != 0:
            return False, f"{test}: gcc failed: {build.stderr[-500:]}"
        proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=timeout)
        last = re.search(r"^(\d+) passed, (\d+) failed$", proc.stdout, re.M)
        if proc.returncode != 0 or last is None or last[2] != "0":
            return False, f"{test}: exit {proc.returncode}, {proc.stdout[-300:]}"
        said.append(f"{test}: {last[0]}")
    return True, "; ".join(said)


_PY_CHECK = r'''
import importlib.util, inspect, sys, numpy as np
from derive.dynamics.equations import derive_dynamics
from derive.dynamics.program import lambdify
from derive.model.spec import load_arm
name, arm_file, module = sys.argv[1:4]
spec = importlib.util.spec_from_file_location(name, module); m = importlib.util.module_from_spec(spec)
spec.loader.exec_module(m)
dyn = derive_dynamics(load_arm(arm_file))
sy = [s for s, _ in dyn.values]; va = [float(v) for _, v in dyn.values]; n = dyn.n
f = lambdify([*dyn.sym.theta, *dyn.sym.dtheta, *sy], list(dyn.J) + list(dyn.G) + list(dyn.gravity))
rng = np.random.default_rng(5)
for k in range(5):
    q, v = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    ref = np.array(f(*q, *v, *va), dtype=float)
    outs = [m.mass_matrix(q), m.bias(q, v), m.gravity(q)]
    assert all(c == m.OK for c, _ in outs), outs
    got = np.concatenate([np.ravel(x) for _, x in outs])
    scale = max(np.max(np.abs(ref)), 1e-300)
    assert np.max(np.abs(got - ref)) <= 1e-9 * scale, (k, np.max(np.abs(got - ref)), scale)
    inp = m.Input(q, v, q + 0.1, np.zeros(n), np.zeros(n))
    code, u, _ = m.mpc_step(inp)
    assert code == m.OK and np.all(np.isfinite(u)), ("mpc_step", code, u)
    for form, State in (("npid", m.NpidState), ("dobc", m.DobcState), ("mom", m.MomState)):
        state = State()
        init = getattr(m, form + "_init")   # the implicit observer's dobc_init takes the sample time
        extra = (0.001,) if "dt" in inspect.signature(init).parameters else ()
        assert init(state, inp, *extra) == m.OK, form + "_init"
        code, u, _ = getattr(m, form + "_step")(state, inp, 0.001)
        assert code == m.OK and np.all(np.isfinite(u)), (form + "_step", code, u)
print("python self-check: J, G, gravity within 1e-9 at 5 states; mpc, npid, dobc, mom steps OK")
'''


def _python_selfcheck(folder: Path, name: str, arm_file: Path, timeout: float) -> Run:
    module = folder / "gen" / name / "python" / f"{name}.py"
    return run_command([sys.executable, "-c", _PY_CHECK, name, str(arm_file), str(module)], folder, timeout)


def _pinocchio_load(path: Path, kind: str = "urdf") -> float | None:
    try:
        import pinocchio as pin
    except ImportError:
        return None
    start = time.perf_counter()
    (pin.buildModelFromMJCF if kind == "mjcf" else pin.buildModelFromUrdf)(str(path))
    return time.perf_counter() - start


def run_arm(arm, folder: Path, timeout: float = TIMEOUT) -> ArmResult:
    """Every command on the corpus arm ``arm`` (tests/corpus.CorpusArm), its URDF already in ``folder``."""
    result = ArmResult(arm.name, None, arm.expect, _pinocchio_load(arm.urdf, arm.kind))
    arm_file = folder / f"{arm.name}.toml"

    def step(command: str, argv: list[str], refuse: str = "") -> bool:
        code, wall, peak, text, cpu = run_command(argv, folder, timeout)
        if code is None:
            ok, detail = False, f"timed out after {timeout:.0f} s"
        elif refuse:
            ok = code == 2 and refuse in text and "Traceback" not in text
            detail = f"refused (exit {code}) as expected" if ok else f"exit {code}: {text[-600:]}"
        else:
            ok, detail = code == 0, "" if code == 0 else f"exit {code}: {text[-600:]}"
        result.commands.append(Step(command, ok, wall, peak, detail, cpu))
        return ok and not refuse

    init = _derive("init", arm.file, "--base", arm.base, "--tip", arm.tip, "--name", arm.name, "--out",
                   arm_file.name, *arm.init_options)
    if not step("init", init, arm.refusal if arm.expect == "refuse" else ""):
        return result
    if arm.locked:
        _write_locked(arm_file, arm.locked)
    found = re.search(r"^\[\[motor\]\]", arm_file.read_text(encoding="utf-8"), re.M)
    result.joints = arm_file.read_text(encoding="utf-8").count("[[motor]]") if found else None
    step("show", _derive("show", arm_file.name))
    step("check", _derive("check", arm_file.name))
    if step("generate", _derive("generate", arm_file.name, "--out", "gen")):
        start = time.perf_counter()
        try:
            ok, detail = _c_selftests(folder, arm.name, timeout)
        except subprocess.TimeoutExpired:
            ok, detail = False, f"timed out after {timeout:.0f} s"
        result.commands.append(Step("selftest-c", ok, time.perf_counter() - start, None, detail))
        code, wall, peak, text, cpu = _python_selfcheck(folder, arm.name, arm_file, timeout)
        result.commands.append(Step("selftest-python", code == 0, wall, peak,
                                    "" if code == 0 else f"exit {code}: {text[-600:]}", cpu))
    if step("simulate", _derive("simulate", arm_file.name, "--out", "sim", "--json", "metrics.json")):
        result.tracking = _tracking(folder / "metrics.json")
    step("fmu --plant", _derive("fmu", arm_file.name, "--plant", "--out", "fmu"))
    result.limits = _limits_truth(folder, arm_file, timeout, result.commands)
    return result


_TRUTH = ("import sys; sys.path.insert(0, sys.argv[1]); from benchmarks.limits_truth import main; "
          "sys.exit(main(sys.argv[2:]))")


def _limits_truth(folder: Path, arm_file: Path, timeout: float, commands: list[Step]) -> dict | None:
    """benchmarks/limits_truth.py on the arm file, in a process of its own (its CPU time and peak memory
    recorded as the command "limits truth"): its JSON, or None when it did not run. Exit 3 (a stated limit
    above the true one) is a finding the goals report, not a failed command."""
    out = folder / "limits_truth.json"
    code, wall, peak, text, cpu = run_command([sys.executable, "-c", _TRUTH, str(ROOT), arm_file.name, "--json",
                                               out.name], folder, timeout)
    ok = code in (0, 3) and out.exists()
    detail = "stated above true" if code == 3 else "" if ok else (
        f"timed out after {timeout:.0f} s" if code is None else f"exit {code}: {text[-600:]}")
    commands.append(Step("limits truth", ok, wall, peak, detail, cpu))
    if not ok:
        return None
    import json

    return json.loads(out.read_text(encoding="utf-8"))


def _tracking(path: Path) -> dict:
    """Per form, the worst joint's RMS and max tracking error [rad or m] of a simulate run's metrics
    (issue 20: the starter file tracks; the figure stated per arm)."""
    import json

    forms = json.loads(path.read_text(encoding="utf-8"))["controllers"]
    out = {}
    for form, c in forms.items():
        links = c["links"]
        worst = max(range(len(links)), key=lambda i: links[i]["rms_error"])
        out[form] = {"joint": worst + 1, "rms": links[worst]["rms_error"],
                     "max": max(x["max_error"] for x in links)}
    return out


def _tracking_cell(result: ArmResult) -> str:
    t = result.tracking
    if not t:
        return "-"
    return "; ".join(f"{f.upper()} {t[f]['rms']:.2g} / {t[f]['max']:.2g} (j{t[f]['joint']})"
                     for f in ("dobc", "npid", "mom", "mpc") if f in t)


def run_corpus(names: tuple[str, ...] = (), timeout: float = TIMEOUT) -> list[ArmResult]:
    sys.path.insert(0, str(ROOT))
    from tests.corpus import corpus_arms

    import compileall

    # derive's bytecode, as an install writes it (pip compiles every module): otherwise each command of a
    # checkout with PYTHONDONTWRITEBYTECODE set compiled some 70 modules again (0.1-0.2 s CPU a command)
    compileall.compile_dir(str(ROOT / "derive"), quiet=1)
    results = []
    for arm in corpus_arms() + corpus_arms("mjcf"):
        if names and arm.name not in names:
            continue
        with tempfile.TemporaryDirectory(prefix=f"corpus-{arm.name}-") as tmp:
            (Path(tmp) / arm.file).write_bytes(arm.urdf.read_bytes())
            results.append(run_arm(arm, Path(tmp), timeout))
        print(f"corpus: {arm.name}: " + ", ".join(f"{c.command} {'ok' if c.ok else 'FAILED'} {c.seconds:.1f} s"
                                                   for c in results[-1].commands), file=sys.stderr, flush=True)
    return results


COLUMNS = ("init", "show", "check", "generate", "selftest-c", "selftest-python", "simulate", "fmu --plant",
           "limits truth")


def _cell(result: ArmResult, command: str) -> str:
    c = next((c for c in result.commands if c.command == command), None)
    if c is None:
        return "-"
    mem = "" if c.peak_mib is None else f", {c.peak_mib:.0f} MiB"
    mark = "" if c.ok else (" TIMEOUT" if "timed out" in c.detail else " FAIL")
    if c.ok and "refused" in c.detail:
        mark = " refused"
    cpu = "" if c.cpu_seconds is None else f"{c.cpu_seconds:.1f} s CPU, "
    return f"{cpu}{c.seconds:.1f} s wall{mem}{mark}"


def markdown(results: list[ArmResult], timeout: float) -> str:
    rows = [[r.name, r.joints if r.joints is not None else "-",
             "-" if r.pinocchio_load_s is None else f"{r.pinocchio_load_s * 1e3:.1f} ms"]
            + [_cell(r, c) for c in COLUMNS] + [_tracking_cell(r)] for r in results]
    failures = [f"- {r.name} `{c.command}`: {c.detail}" for r in results for c in r.commands if not c.ok]
    limited = [r for r in results if r.limits]
    return "\n\n".join([
        table(("arm", "joints", "Pinocchio load") + COLUMNS + ("tracking",), rows),
        f"CPU time (user + system), wall time and peak memory per command (timeout {timeout:.0f} s of wall time "
        "per command); the goals read the CPU time. Tracking: the starter file's own simulate run, per form the "
        "worst joint's RMS / max tracking error [rad] over the run (and which joint); MPC alone has no observer.",
        "Failures:\n\n" + "\n".join(failures) if failures else "No failures.",
        *(limits_markdown(limited) if limited else [])])


# issue 33's goals: CPU seconds per command and peak MiB, by the number of joints (6-7, 8, 12); issue 19's
# fmu --plant < 30 s for 7 joints beside them
BUDGETS = ((6, 7, "6-7", {"init": 5.0, "show": 5.0, "check": 30.0, "generate": 15.0, "simulate": 30.0,
                          "fmu --plant": 30.0}, 1024),
           (8, 8, "8", {"init": 10.0, "show": 10.0, "check": 45.0, "generate": 30.0, "simulate": 60.0}, 1024),
           (12, 12, "12", {"init": 30.0, "show": 30.0, "check": 120.0, "generate": 60.0, "simulate": 120.0}, 2048))


def goals(results: list[ArmResult]) -> tuple[Goal, ...]:
    """Issue 33's goals per class of arm (BUDGETS: CPU seconds per command, peak memory) for the classes
    the run holds; issue 34's for the sample-time limits (every arm: benchmarks.corpus_limits.limit_goals)."""
    out = []
    for low, high, label, limits, mib in BUDGETS:
        arms = [r for r in results if r.joints is not None and low <= r.joints <= high]
        for command, limit in limits.items():
            times = [(r.name, c.cpu_seconds if c.cpu_seconds is not None else c.seconds, c.ok)
                     for r in arms for c in r.commands if c.command == command]
            if times:
                worst = max(times, key=lambda x: x[1])
                over = [f"{name} {t:.1f} s" for name, t, ok in times if not (ok and t < limit)]
                out.append(Goal(f"{label}-joint arms: {command} under {limit:g} s of CPU", not over,
                                f"slowest {worst[0]}: {worst[1]:.1f} s" + (f"; over: {', '.join(over)}" if over else "")))
        peaks = [(r.name, c.command, c.peak_mib) for r in arms for c in r.commands if c.peak_mib is not None]
        if peaks:
            worst = max(peaks, key=lambda x: x[2])
            out.append(Goal(f"{label}-joint arms: every command under {mib} MiB", worst[2] < mib,
                            f"largest {worst[0]} {worst[1]}: {worst[2]:.0f} MiB"))
    return tuple(out) + tuple(limit_goals(results))


def run() -> Section:
    """The ``make bench`` section: every corpus arm, every command."""
    results = run_corpus()
    return Section(TITLE, (markdown(results, TIMEOUT),), goals(results))


def main(argv: list[str]) -> int:
    out = Path("build/corpus")
    if argv[:1] == ["--out"]:
        out, argv = Path(argv[1]), argv[2:]
    results = run_corpus(tuple(argv))
    out.mkdir(parents=True, exist_ok=True)
    (out / "corpus.json").write_text(dumps({"timeout_s": TIMEOUT, "arms": [asdict(r) for r in results]}),
                                     encoding="utf-8")   # strict JSON (derive.jsonio)
    text = f"# URDF and MJCF corpus\n\n{markdown(results, TIMEOUT)}\n\n" + "\n".join(g.line() for g in goals(results)) + "\n"
    (out / "corpus.md").write_text(text, encoding="utf-8")
    print(text)
    return 1 if any(not c.ok for r in results for c in r.commands) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
