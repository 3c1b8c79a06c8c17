"""Monte-Carlo sweeps: many compiled closed-loop runs under a distribution of
plants (the arm file's ``[sweep]``, derive.model.sweepspec), dispatched through a
``concurrent.futures`` executor (local processes, or a Dask cluster's executor),
with results that do not depend on the number of workers.

Sample i draws its parameters and its noise seed from ``SeedSequence([seed, i])``
only, runs every controller in compiled code (derive.sim.compiled), and returns
its metrics and its tracking error decimated to at most ENVELOPE_POINTS samples;
the parent gathers the results in index order.
"""
from __future__ import annotations

import math
from concurrent.futures import Executor, as_completed
from dataclasses import dataclass, replace

import numpy as np

from derive.errors import DeriveError
from derive.jsonio import Undefined, rounded
from derive.model.simspec import SimSettings
from derive.model.spec import Arm
from derive.model.sweepspec import METRICS, PARAMETERS, Criterion, Distribution, SweepSpec

ENVELOPE_POINTS = 600
MAX_REDRAWS = 10_000


def draw(rng: np.random.Generator, dist: Distribution) -> float:
    """One draw of ``dist`` (truncated distributions draw again outside their bounds)."""
    for _ in range(MAX_REDRAWS):
        if dist.kind == "uniform":
            return float(rng.uniform(dist.a, dist.b))
        if dist.kind == "normal":
            v = float(rng.normal(dist.a, dist.b))
        else:
            v = float(dist.a * math.exp(dist.b * rng.standard_normal()))
        if (dist.low is None or v >= dist.low) and (dist.high is None or v <= dist.high):
            return v
    raise DeriveError(f"sweep: no draw of {dist.kind}({dist.a:g}, {dist.b:g}) fell within "
                      f"[{dist.low}, {dist.high}] in {MAX_REDRAWS} tries; widen the bounds")


def sample_settings(base: SimSettings, spec: SweepSpec, index: int, n: int) -> tuple[SimSettings, dict]:
    """The simulation settings of sample ``index`` and the values drawn for it
    (from ``SeedSequence([spec.seed, index])`` alone: any worker, same sample)."""
    noise_seq, draw_seq = np.random.SeedSequence([spec.seed, index]).spawn(2)
    rng = np.random.default_rng(draw_seq)
    updates: dict = {"seed": int(noise_seq.generate_state(1)[0])}
    if spec.duration is not None:
        updates["duration"] = spec.duration
    drawn: dict = {}
    for name, dist in spec.vary:
        key, per, factor = PARAMETERS[name]
        values = [draw(rng, dist) for _ in range({"arm": 1, "component": 3}.get(per, n))]
        drawn[name] = values[0] if per == "arm" else values
        if per == "arm":
            updates[key] = values[0]
        elif factor:
            updates[key] = tuple(o * v for o, v in zip(getattr(base, key), values))
        else:
            updates[key] = tuple(values)
    return replace(base, **updates), drawn


@dataclass(frozen=True)
class Payload:
    """What every worker needs once: the arm, the compiled loop, the controllers, the plant
    (derive.sim.plants: derive's, or MuJoCo's with its stripped model file)."""

    arm: Arm
    loop: object   # derive.sim.compiled.LoopBuild
    names: tuple[str, ...]
    plant: object = None   # derive.sim.plants.PlantSource; None: derive's


@dataclass(frozen=True)
class SampleResult:
    """One sample: drawn values, per controller the metrics per link (or the
    failure message) and the decimated tracking error (points x n)."""

    index: int
    drawn: dict
    settings: SimSettings
    metrics: dict
    failures: dict
    t: np.ndarray
    errors: dict


_DERIVED: dict = {}


def run_chunk(payload: Payload, jobs: list[tuple[int, SimSettings, dict]]) -> list[SampleResult]:
    """Run samples (index, settings, drawn) in this process; the derivation is made
    once per process (a worker on another machine gets the arm, not SymPy objects)."""
    from derive.control.pipeline import derive
    from derive.sim.plants import DerivedPlant
    from derive.sim.simulate import metrics

    key = payload.loop.key
    if key not in _DERIVED:
        _DERIVED[key] = derive(payload.arm)
    d = _DERIVED[key]
    plant = payload.plant or DerivedPlant()
    out = []
    for index, s, drawn in jobs:
        res, fails, errs = {}, {}, {}
        t = None
        for name in payload.names:
            tr = plant.run(d, payload.loop, s, name)
            steps = int(round(s.duration / s.sample_time))
            stride = max(1, math.ceil(steps / ENVELOPE_POINTS))
            t = np.arange(0, steps, stride) * s.sample_time
            if tr.failure is not None:
                fails[name] = tr.failure.message(name)
                errs[name] = None
                continue
            # an undefined figure (jsonio.Undefined) is NaN here: the summary leaves it out
            res[name] = [{k: math.nan if isinstance(v, Undefined) else v for k, v in m.items()} for m in metrics(tr, s)]
            errs[name] = (tr.yd - tr.theta)[::stride]
        out.append(SampleResult(index, drawn, s, res, fails, t, errs))
    return out


def run_sweep(payload: Payload, base: SimSettings, spec: SweepSpec, samples: int, executor: Executor | None,
              workers: int, bar=None, scatter=None) -> list[SampleResult]:
    """Every sample, in index order. ``executor`` None runs here; ``scatter``
    (Dask's Client.scatter) ships the payload to the workers once."""
    n = payload.arm.n
    jobs = [(i, *sample_settings(base, spec, i, n)) for i in range(samples)]
    if executor is None:
        results = []
        for job in jobs:
            results += run_chunk(payload, [job])
            if bar is not None:
                bar.update()
        return results
    size = max(1, math.ceil(samples / (4 * max(1, workers))))
    chunks = [jobs[i:i + size] for i in range(0, samples, size)]
    shipped = scatter(payload) if scatter is not None else payload
    futures = [executor.submit(run_chunk, shipped, chunk) for chunk in chunks]
    results = []
    for fut in as_completed(futures):
        part = fut.result()
        results += part
        if bar is not None:
            bar.update(len(part))
    return sorted(results, key=lambda r: r.index)


# Figures of sweep reports at a stated precision, written like metrics.json (issue 10, item 9):
# a run's last bits depend on the CPU and libm, the committed sweep.json must not.
SWEEP_DIGITS = 6


def sig(x: float | None, digits: int = SWEEP_DIGITS) -> float | None:
    """``x`` rounded to ``digits`` significant digits (jsonio.rounded, as sweep.json is
    written); None for None or a non-finite x."""
    if x is None or not math.isfinite(x):
        return None
    return rounded(x, digits)


def criterion_value(c: Criterion, links: list[dict]) -> float:
    """The metric a criterion checks, worst over its links."""
    idx = range(len(links)) if c.link is None else [c.link - 1]
    vals = [links[i][c.metric] for i in idx]
    return max(v if math.isfinite(v) else math.inf for v in vals)


def summarize(results: list[SampleResult], spec: SweepSpec, names: tuple[str, ...], n: int) -> dict:
    """Per controller: percentiles of every metric per link, pass fractions, the worst sample."""
    out = {}
    criteria = spec.criteria or (Criterion("steady_state_error", math.inf),)
    for name in names:
        ok = [r for r in results if name in r.metrics]
        entry: dict = {"runs": len(results), "failed_runs": len(results) - len(ok)}
        pct: dict = {}
        for metric in METRICS:
            rows = []
            for i in range(n):
                vals = np.array([r.metrics[name][i][metric] for r in ok], dtype=float)
                vals = vals[np.isfinite(vals)]
                if len(vals) == 0:
                    why = Undefined(f"no finished run of {name} gave this figure")
                    rows.append({"link": i + 1, "p5": why, "p50": why, "p95": why, "max": why})
                    continue
                p5, p50, p95 = np.percentile(vals, [5, 50, 95])
                rows.append({"link": i + 1, "p5": sig(p5), "p50": sig(p50), "p95": sig(p95), "max": sig(vals.max())})
            pct[metric] = rows
        entry["percentiles"] = pct
        if spec.criteria:
            passes = {c.label(): [name in r.metrics and criterion_value(c, r.metrics[name]) <= c.max for r in results]
                      for c in spec.criteria}
            every = [all(p[k] for p in passes.values()) for k in range(len(results))]
            entry["pass_fraction"] = {**{label: sig(sum(v) / len(v)) for label, v in passes.items()},
                                      "all criteria": sig(sum(every) / len(every))}
        first = criteria[0]
        ranked = [(criterion_value(first, r.metrics[name]) if name in r.metrics else math.inf, -r.index, r)
                  for r in results]
        value, _, worst = max(ranked, key=lambda x: (x[0], x[1]))
        entry["worst"] = {"sample": worst.index, "metric": first.metric,
                          "links": "every" if first.link is None else first.link,
                          "value": sig(value) if math.isfinite(value) else Undefined(
                              f"the run failed: {worst.failures[name]}" if name in worst.failures
                              else f"{first.metric} undefined in this run"),
                          "parameters": {k: _round_drawn(v) for k, v in worst.drawn.items()},
                          "failed": worst.failures.get(name), "file": f"worst_{name}.toml"}
        out[name] = entry
    return out


def _round_drawn(v):
    return [sig(x) for x in v] if isinstance(v, list) else sig(v)


def worst_settings(results: list[SampleResult], summary: dict) -> dict[str, SimSettings]:
    """The full simulation settings of each controller's worst sample."""
    by_index = {r.index: r for r in results}
    return {name: by_index[entry["worst"]["sample"]].settings for name, entry in summary.items()}
