"""``derive simulate``: closed-loop runs of the generated controllers, with
plots and a metrics table (Markdown; JSON with --json)."""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from derive import jsonio
from derive.errors import DeriveError
from derive.model.actuators import input_word, units_text
from derive.model.chain import Actuation
from derive.sim.simulate import CONTROLLERS, VARIANTS
from derive.cli.simulate_report import (described, metrics_json, metrics_markdown, metrics_results,  # noqa: F401
                                        range_warnings, stiffness_words)  # (metrics_json, metrics_markdown: re-exported)


def add_arguments(parser) -> None:
    """CLI: derive simulate [ARM] [--controllers ...] [--backend python|c] [--observer explicit|implicit]
    [--out DIR] [--json FILE]."""
    from derive.cli import add_arm_argument

    add_arm_argument(parser)
    parser.add_argument("--controllers", default=",".join(CONTROLLERS),
                        help=f"comma-separated, of {', '.join(VARIANTS)} (default {','.join(CONTROLLERS)}: "
                             "mom is the generalized-momentum observer)")
    parser.add_argument("--backend", choices=("compiled", "python", "c"), default="compiled",
                        help="compiled: the whole closed loop in C (default); python, c: the Python-stepped "
                             "reference with the generated Python module or C library as controller")
    parser.add_argument("--out", default=None, help="folder for plots and metrics.md (default sim/<arm>)")
    parser.add_argument("--json", default=None, help="also write the metrics as JSON to this file")
    parser.add_argument("--duration", type=float, default=None, help="override simulation.duration [s]")
    parser.add_argument("--observer", choices=("explicit", "implicit"), default=None,
                        help="the controllers' observer step, as derive generate --observer (default: the arm "
                             "file's controller.observer, else explicit)")
    parser.add_argument("--reference-from-pose", action="store_true",
                        help="start the reference at the arm's initial pose, y_d(0) = C theta(0), the pulse train "
                             "added to it (as [simulation] reference_start = \"measured\"): e(0) = 0, so the "
                             "initial estimate dhat(0) is 0, a smooth start")
    parser.add_argument("--force", action="store_true",
                        help="simulate even when the sample time is above a form's limit (derive check prints it) or "
                             "the plant's RK4 step is unstable in its stiffest mode")
    parser.add_argument("--voltage-limits", "--input-limits", dest="voltage_limits", default=None,
                        metavar="U1,U2,...",
                        help="override the motors' input limits (0 = none), for saturation studies: a voltage "
                             "limit [V] of a DC motor, a torque limit [N m] in torque mode")
    add_plant_arguments(parser)
    parser.add_argument("--no-cache", action="store_true",
                        help="derive and compile anew and keep nothing: by default the derivation, the compiled loop "
                             "and the figures are kept in the user's cache folder ($DERIVE_CACHE_DIR, else "
                             "platformdirs' user_cache_dir('derive')) per arm file, the files it reads, the options "
                             "and derive's version (derive.sim.cache)")
    parser.add_argument("--compare", action="store_true",
                        help="run the other plant too (derive's and MuJoCo's), with the same settings, and report "
                             "the difference of the trajectories (metrics comparison, plant_difference.png)")


def add_plant_arguments(parser) -> None:
    """--plant and --mujoco-friction (derive simulate and derive sweep)."""
    from derive.sim.plants import PLANTS

    parser.add_argument("--plant", choices=PLANTS, default="derive",
                        help="derive: the arm's own derivation with the [simulation] mismatch (default); mujoco: "
                             "MuJoCo integrating the arm's URDF, or [simulation] mujoco_model (an MJCF or URDF; "
                             "pip install 'derive[mujoco]')")
    parser.add_argument("--mujoco-friction", choices=("file", "off"), default="file",
                        help="file: MuJoCo keeps the joint damping, friction loss and limits the URDF or MJCF gives "
                             "(default); off: derive's damping, no friction loss, no limits or contacts (both "
                             "plants then have the same parameters)")


MAX_SAMPLES = 1 << 25   # steps x joints of one run: each trace array 256 MiB (several per controller) at most


def too_many(settings, n: int) -> None:
    """A DeriveError (derive exits 2 with its message), before anything runs, when the experiment's steps
    times the joints pass MAX_SAMPLES (a 12-joint chain's starter sample time of 5e-08 s, set by its
    forward-Euler observer step, over 30 s was 600 million steps: a MemoryError of 54 GiB in the pulse train)."""
    steps = int(round(settings.duration / settings.sample_time))
    if steps * n > MAX_SAMPLES:
        raise DeriveError(f"simulate: [simulation] sample_time = {settings.sample_time:g} s over duration = "
                          f"{settings.duration:g} s is {steps:,} steps of {n} joints, past the limit of {MAX_SAMPLES:,} "
                          f"samples (steps x joints) a run keeps in memory; raise sample_time (derive check states "
                          f"the sample-time limits of each form and observer step: --observer implicit allows far longer "
                          f"ones for a stiff observer) or shorten --duration (at most "
                          f"{MAX_SAMPLES // n * settings.sample_time:.3g} s at this sample time)")


def simulate_files(arm, names: list[str], backend_kind: str, progress: bool = False,
                   duration: float | None = None, observer: str = "explicit", plant: str = "derive",
                   friction: str = "file", compare: bool = False, warn=None,
                   cache=None) -> tuple[dict[str, bytes], dict]:
    """Run the controllers on ``plant`` (derive.sim.plants; with ``compare`` on the other plant
    too); return {file name: bytes} (PNG, metrics.md) and the metrics.

    A controller whose run fails keeps its samples up to the failure (plotted and
    marked), gets no metrics and a ``failed`` entry; the others are unaffected.
    ``warn(text)``, when given, receives the start's warnings before anything runs
    (an initial estimate dhat(0) above an input limit: derive.sim.start) and, after the runs,
    each joint that left the range its URDF or arm file states (range_warnings). ``cache``: the entry of
    derive.sim.cache that holds the derivation, the compiled loop and the figures (None: none)."""
    from dataclasses import replace

    from derive.sim import plants
    from derive.sim.cache import SimCache

    cache = SimCache(None) if cache is None else cache
    settings = arm.simulation if duration is None else replace(arm.simulation, duration=duration)
    too_many(settings, len(arm.motors))
    main = plants.select(arm, plant, friction)
    sources = [main, plants.select(arm, "mujoco" if plant == "derive" else "derive", friction)] if compare else [main]
    d = cached_derivation(arm, cache)
    if warn is not None and {"dobc", "npid", "npid_unprotected"} & set(names):
        from derive.sim.start import start_warnings

        for text in start_warnings(d, settings, observer):
            warn(text)
    runs = _runs(d, sources, names, backend_kind, settings, observer, progress, cache)
    traces = runs[0]
    if warn is not None:
        for text in range_warnings(d, traces):
            warn(text)
    unit, word = units_text(arm.input_units), input_word(arm.input_units)
    results = metrics_results(traces, settings, unit, described(main, d, settings))
    files = {f"link{i + 1}.png": cache.figure(("link", i, arm.input_units[i]), traces,
                                              lambda i=i: _plots().link_figure(traces, i, arm.input_units[i]))
             for i in range(d.n)}
    files["tracking_error.png"] = cache.figure(("error",), traces, lambda: _plots().error_figure(traces))
    if compare:
        results["comparison"] = plants.compare(traces, runs[1], sources[1].describe(d, settings))
        files["plant_difference.png"] = cache.figure(
            ("difference", main.name, sources[1].name), [*traces, *runs[1]],
            lambda: _plots().difference_figure(traces, runs[1], main.name, sources[1].name))
    files["metrics.md"] = metrics_markdown(arm.name, results["controllers"], backend_kind, unit, word,
                                           plant=results["plant"], comparison=results.get("comparison")).encode()
    written = getattr(main, "model", None) and main.model(d, settings).xml   # MuJoCo's model, for its viewer
    if written:
        files[MUJOCO_XML] = written.encode()
    return files, results


MUJOCO_XML = "mujoco_model.xml"   # the MJCF MuJoCo integrated (derive.sim.mujoco.model, step 7)


def _plots():
    """derive.sim.plots, imported when a figure is drawn (matplotlib takes a second to import)."""
    from derive.sim import plots

    return plots


def cached_derivation(arm, cache):
    """The derivation of ``arm``: the one of the cache entry ``cache`` (derive.sim.cache), else derived
    (and kept there)."""
    from derive.control.pipeline import derive

    return cache.get("derivation", lambda: derive(arm))


def _runs(d, sources, names, backend_kind: str, settings, observer: str, progress: bool, cache) -> list[list]:
    """The traces of the controllers ``names`` on each plant of ``sources``; the compiled loop from
    ``cache`` (derive.sim.cache), else built (and kept there)."""
    from derive.progress import progress as bar
    from derive.sim.plants import build
    from derive.sim.simulate import run_many

    if backend_kind == "compiled":
        payload = settings.payload_mass > 0   # J_p, G_p only when the run has a payload (derive.sim.plants.build)
        loop = cache.get("loop_payload" if payload else "loop", lambda: build(d, observer, sources, payload))
        out = []
        with bar(total=len(names) * len(sources), desc="simulating", unit="run", disable_bar=not progress) as b:
            for src in sources:
                out.append([])
                for name in names:
                    out[-1].append(src.run(d, loop, settings, name))
                    b.update()
        return out
    from derive.sim.backends import Backend

    backend = Backend(d, backend_kind, observer=observer)
    try:
        return [list(run_many(d, backend, src.stepped(d, settings), settings, names, progress).values())
                for src in sources]
    finally:
        backend.close()


def with_voltage_limits(arm, text: str):
    """``arm`` with the motors' input limits replaced (``--voltage-limits``, ``--input-limits``): the
    voltage limit of a DC motor [V], the torque limit in torque mode [N m]."""
    import math
    from dataclasses import replace
    from fractions import Fraction

    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != arm.n or not all(math.isfinite(v) and v >= 0 for v in values):
        raise DeriveError(f"--voltage-limits: expected {arm.n} comma-separated finite numbers >= 0 "
                          f"([{units_text(arm.input_units)}], 0 = none), got {text!r}")
    motors = tuple(replace(m, **{"voltage_limit" if m.actuation is Actuation.VOLTAGE else "torque_limit":
                                 Fraction(repr(v)) if v > 0 else None})
                   for m, v in zip(arm.motors, values))
    return replace(arm, motors=motors)


def _json_inside(json_path: Path | None, out: Path) -> str | None:
    """The path of ``--json`` relative to ``--out`` (POSIX) when it lies inside it, else None."""
    if json_path is None:
        return None
    try:
        rel = json_path.resolve().relative_to(out.resolve())
    except ValueError:
        return None
    return rel.as_posix() if rel.parts else None


def _json_folder_check(json_path: Path) -> None:
    """``--json`` outside ``--out``: its folder exists or can be made (its nearest existing
    ancestor is a folder); one DeriveError otherwise, before anything is simulated."""
    folder = json_path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise DeriveError(f"--json {json_path}: expected a file in a folder, got {folder}, which is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise DeriveError(f"--json {json_path}: expected a folder derive may write in, got {folder}, "
                          "which is not writable")


def run(args) -> int:
    from derive.codegen.emit import write_tree
    from derive.cli import load_cli_arm

    names = [c.strip() for c in args.controllers.split(",") if c.strip()]
    unknown = [c for c in names if c not in VARIANTS]
    if unknown or not names:
        raise DeriveError(f"--controllers: expected a comma-separated list of {', '.join(VARIANTS)}, "
                          f"got {args.controllers!r}")
    if args.duration is not None and not (0 < args.duration < 1e6):
        raise DeriveError(f"--duration: expected a number of seconds > 0, got {args.duration}")
    json_path = Path(args.json) if args.json else None
    arm = load_cli_arm(args)
    args.observer = args.observer or arm.controller.observer   # the arm file's step unless --observer
    out = Path(args.out) if args.out else Path("sim") / arm.name
    inside = _json_inside(json_path, out)   # in the --out folder: written after it
    if json_path is not None and inside is None:   # fail before minutes of simulation
        _json_folder_check(json_path)
    own = {"MANIFEST.json", "metrics.md", "tracking_error.png", *(f"link{i + 1}.png" for i in range(arm.n)),
           *(("plant_difference.png",) if args.compare else ()), *((MUJOCO_XML,) if args.plant == "mujoco" else ())}
    if inside in own:
        raise DeriveError(f"--json {json_path}: expected a file name other than derive simulate's own "
                          f"{inside} in --out {out}")
    if args.voltage_limits is not None:
        arm = with_voltage_limits(arm, args.voltage_limits)
    if args.reference_from_pose:
        from dataclasses import replace

        arm = replace(arm, simulation=replace(arm.simulation, reference_start="measured"))
    from derive.sim import plants
    from derive.sim.cache import SimCache

    used = tuple(dict.fromkeys([args.plant, *(plants.PLANTS if args.compare else ())]))
    for plant in used:   # before the derivation
        plants.select(arm, plant, args.mujoco_friction)
    # the Python and C backends generate their controller from the derivation: only the compiled
    # loop's runs take a cached one (its loop built from the derivation it was kept with)
    cache = SimCache.open(arm, {"observer": args.observer, "plants": used, "friction": args.mujoco_friction},
                          enabled=not args.no_cache and args.backend == "compiled")
    if not args.force:   # the sampled loop's limit (derive.control.sampling): refuse before simulating
        from derive.control.sampling.limit_text import too_slow
        from derive.sim.simulate import VARIANTS as forms

        used_forms = tuple(sorted({forms[c][0] for c in names}))
        slow = cache.get(("too_slow", used_forms), lambda: too_slow(cached_derivation(arm, cache),
                                                                     arm.simulation.sample_time, list(used_forms),
                                                                     args.observer))
        if slow:
            raise DeriveError(f"simulation.sample_time of {arm.name}: " + "; ".join(slow)
                              + ": the controller would diverge; lower sample_time below the limits named, use "
                              "--observer implicit where it allows the sample time, or pass --force")
        from derive.sim.plant import stiffest_mode

        for name in used:   # RK4 unstable in the plant's stiffest mode: trajectories known to be wrong
            source = plants.select(arm, name, args.mujoco_friction)
            d = cached_derivation(arm, cache)
            stiff = stiffest_mode(d, arm.simulation, source.coulomb(d, arm.simulation))
            if not stiff["stable"]:
                raise DeriveError(f"simulation.substeps of {arm.name} = {arm.simulation.substeps}, {name}'s plant: "
                                  f"{stiffness_words(stiff, arm.simulation)}, or pass --force")
    start = time.perf_counter()
    files, results = simulate_files(arm, names, args.backend, progress=True, duration=args.duration,
                                    observer=args.observer, plant=args.plant, friction=args.mujoco_friction,
                                    compare=args.compare,
                                    warn=lambda text: print(f"derive: warning: {text}", file=sys.stderr),
                                    cache=cache)
    cache.save()
    wall = time.perf_counter() - start
    write_tree(out, {"MANIFEST.json": jsonio.dumps({"_note": "generated by derive simulate; do not edit",
                                                    "files": sorted(files)}, sort_keys=False),
                     **{k: v.decode() for k, v in files.items() if k.endswith((".md", ".xml"))}},
               binary={k: v for k, v in files.items() if k.endswith(".png")})
    if json_path is not None:   # after the folder: --json may lie in it (made by write_tree) or elsewhere
        try:
            json_path.parent.mkdir(parents=True, exist_ok=True)
            json_path.write_text(metrics_json(results))
        except OSError as exc:
            raise DeriveError(f"--json {json_path}: cannot write ({exc.strerror or exc})") from None
    simulated = (args.duration or arm.simulation.duration) * len(names) * (2 if args.compare else 1)
    kept = f"; derivation and compiled loop from the cache {cache.path}" if cache.hit else ""
    print(f"derive: simulated {simulated:g} s in {wall:.1f} s ({simulated / wall:.1f} simulated s per "
          f"wall s){kept}; wrote {out}", file=sys.stderr)
    stiff = results["plant"]["stiffest_mode"]
    if not stiff["stable"]:
        print(f"derive: warning: {stiffness_words(stiff, arm.simulation)}", file=sys.stderr)
    failed = [entry["failed"]["message"] for entry in results["controllers"].values() if entry.get("failed")]
    for message in failed:
        print(f"derive: error: {message}", file=sys.stderr)
    if failed:
        print(f"derive: {len(failed)} of {len(names)} runs failed; the others' results are written", file=sys.stderr)
    return 1 if failed else 0
