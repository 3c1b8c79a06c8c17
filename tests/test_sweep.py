"""Monte-Carlo sweeps (issue 13 items 2, 3): the same results whatever the
workers (1 or 2 local processes, a Dask cluster), the worst sample rerun by
``derive simulate``, bad [sweep] input refused with one message and exit 2."""
from __future__ import annotations

import re

import pytest

from derive import jsonio
from derive.cli import main
from derive.model.spec import resolve_arm_path

SWEEP = """
[simulation]
pulse_period = 6.0
start = [0.0, 1.0]

[sweep]
samples = 8
seed = 11
controllers = ["mpc", "dobc", "npid"]
duration = 8.0

[sweep.vary]
payload_scale = { distribution = "uniform", low = 0.7, high = 1.3 }
coulomb_friction = { distribution = "lognormal", median = 1.0, sigma = 0.5, low = 0.5, high = 2.0 }
disturbance = { distribution = "normal", mean = 0.0, sd = 0.3, low = -0.5, high = 0.5 }
link_mass = { distribution = "uniform", low = 0.9, high = 1.1 }
velocity_noise = { distribution = "uniform", low = 0.0, high = 0.01 }
payload_mass = { distribution = "uniform", low = 0.0, high = 0.3 }
payload_com = { distribution = "uniform", low = -0.05, high = 0.05 }

[[sweep.criterion]]
metric = "steady_state_error"
max = 0.01
"""


def _arm(tmp_path, sweep: str = SWEEP):
    text = resolve_arm_path(None).read_text()
    text = text[: text.index("[sweep]")] if "[sweep]" in text else text
    path = tmp_path / "arm.toml"
    path.write_text(text + sweep)
    return path


def _sweep(tmp_path, arm, tag, *options):
    out = tmp_path / f"out_{tag}"
    js = tmp_path / f"{tag}.json"
    assert main(["sweep", str(arm), "--out", str(out), "--json", str(js), *options]) == 0
    return out, js.read_bytes()


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sweep")
    arm = _arm(tmp)
    one = _sweep(tmp, arm, "one", "--workers", "1")
    two = _sweep(tmp, arm, "two", "--workers", "2")
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        dask = _sweep(tmp, arm, "dask", "--dask", cluster.scheduler_address)
    return tmp, one, two, dask


def test_sweep_json_is_byte_identical_for_1_and_2_workers_and_a_dask_cluster(sweeps):
    tmp, one, two, dask = sweeps
    assert one[1] == two[1] == dask[1]
    data = jsonio.loads(one[1])
    assert data["samples"] == 8 and set(data["results"]) == {"mpc", "dobc", "npid"}
    fractions = {name: e["pass_fraction"]["all criteria"] for name, e in data["results"].items()}
    assert fractions["mpc"] == 0.0 and fractions["dobc"] > 0.5, fractions  # the paper's claim, in small
    for name in ("envelope.png", "histograms.png", "summary.md", "worst_dobc.toml"):
        assert (one[0] / name).stat().st_size > 500, name
    assert (one[0] / "envelope.png").read_bytes() == (two[0] / "envelope.png").read_bytes()
    drawn = data["results"]["dobc"]["worst"]["parameters"]   # issue 38: the payload drawn, its com per component
    assert 0.0 <= drawn["payload_mass"] <= 0.3 and len(drawn["payload_com"]) == 3, drawn
    assert all(-0.05 <= x <= 0.05 for x in drawn["payload_com"]), drawn


def test_worst_sample_rerun_with_simulate_gives_the_reported_metric(sweeps, tmp_path):
    tmp, one, _, _ = sweeps
    data = jsonio.loads(one[1])
    for name in ("mpc", "dobc"):
        worst = data["results"][name]["worst"]
        js = tmp_path / f"{name}.json"
        assert main(["simulate", str(one[0] / worst["file"]), "--controllers", name, "--out",
                     str(tmp_path / name), "--json", str(js)]) == 0
        links = jsonio.loads(js.read_text())["controllers"][name]["links"]
        value = max(link[worst["metric"]] for link in links)
        assert value == pytest.approx(worst["value"], rel=1e-5), (name, value, worst)


def test_sample_draws_depend_on_seed_and_index_only():
    import derive
    from derive.sim.sweep import sample_settings
    import tomllib
    from derive.model.sweepspec import parse_sweep

    spec, problems = parse_sweep(tomllib.loads(SWEEP)["sweep"], 2)
    assert not problems
    base = derive.load_arm().simulation
    a = sample_settings(base, spec, 5, 2)
    assert a == sample_settings(base, spec, 5, 2) and a != sample_settings(base, spec, 6, 2)
    settings, drawn = a
    assert 0.7 <= drawn["payload_scale"] <= 1.3 and all(-0.5 <= v <= 0.5 for v in drawn["disturbance"])
    assert all(0.5 <= v <= 2.0 for v in drawn["coulomb_friction"])
    assert settings.coulomb_friction == tuple(c * f for c, f in zip(base.coulomb_friction, drawn["coulomb_friction"]))


BAD = [
    ("unknown distribution", 'payload_scale = { distribution = "gamma", low = 0.5, high = 1.5 }',
     r"sweep\.vary\.payload_scale\.distribution: expected one of uniform, normal, lognormal, got 'gamma'"),
    ("lower above upper", 'payload_scale = { distribution = "uniform", low = 1.5, high = 0.5 }',
     r"sweep\.vary\.payload_scale\.low: expected at most high = 0\.5, got 1\.5"),
    ("negative sd", 'position_noise = { distribution = "normal", mean = 0.0, sd = -0.1, low = 0.0 }',
     r"sweep\.vary\.position_noise\.sd: expected a number >= 0, got -0\.1"),
    ("unknown parameter", 'tip_colour = { distribution = "uniform", low = 0.0, high = 1.0 }',
     r"sweep\.vary\.tip_colour: expected one of payload_scale"),
]


@pytest.mark.parametrize("case,line,message", BAD, ids=[b[0] for b in BAD])
def test_bad_sweep_distribution_is_one_clear_error_exit_2_nothing_written(tmp_path, capsys, case, line, message):
    arm = _arm(tmp_path, SWEEP.replace('payload_scale = { distribution = "uniform", low = 0.7, high = 1.3 }', line))
    assert main(["sweep", str(arm), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert err.count("derive: error") == 1 and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("sweep,options,message", [
    (SWEEP.replace('metric = "steady_state_error"', 'metric = "settling_time"'), [],
     r"sweep\.criterion\[1\]\.metric: expected one of rms_error, .*, got 'settling_time'"),
    (SWEEP.replace("samples = 8", "samples = 0"), [], r"sweep\.samples: expected a whole number >= 1, got 0"),
    (SWEEP, ["--samples", "0"], r"--samples: expected a whole number >= 1, got 0"),
    (SWEEP.replace('"npid"]', '"pid"]'), [], r"sweep\.controllers: expected names of mpc, .*got \['pid'\]"),
], ids=["unknown metric", "zero samples in file", "zero samples option", "unknown controller"])
def test_bad_sweep_settings_are_one_clear_error_exit_2_nothing_written(tmp_path, capsys, sweep, options, message):
    arm = _arm(tmp_path, sweep)
    assert main(["sweep", str(arm), "--out", str(tmp_path / "out"), *options]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert err.count("derive: error") == 1 and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def _synthetic(factor: float) -> list:
    """Eight samples of made-up metrics (every figure times ``factor``: another machine's
    last bits): npid finished, dobc without a steady-state error (a run too short to settle,
    NaN as run_chunk stores an undefined figure), mpc failed every time."""
    import math

    from derive.model.sweepspec import METRICS
    from derive.sim.sweep import SampleResult

    out = []
    for i in range(8):
        links = [{m: (1.0 + 0.37 * i + 0.11 * k) * 10.0 ** -(j + 2) * factor for k, m in enumerate(METRICS)}
                 for j in range(2)]
        metrics = {"npid": links, "dobc": [dict(link, steady_state_error=math.nan) for link in links]}
        out.append(SampleResult(i, {"payload_scale": (0.8 + 0.05 * i) * factor}, None, metrics,
                                {"mpc": "mpc: the controller step returned 1 at t = 3 s"}, None, {}))
    return out


def test_sweep_json_states_its_precision_and_does_not_carry_the_last_bits():
    """Issue 10, item 9 for sweeps: sweep.json is written like metrics.json (strict JSON,
    every figure at a stated precision: SWEEP_DIGITS significant digits), so figures that
    differ in their last bits (1e-12 relative) give the same bytes; an undefined percentile
    or worst value is null with its reason beside it; summary.md is made from the JSON."""
    import tomllib

    from derive.cli.sweep import summary_markdown, sweep_data, sweep_json
    from derive.model.sweepspec import parse_sweep
    from derive.sim.sweep import SWEEP_DIGITS, summarize

    spec, problems = parse_sweep(tomllib.loads(SWEEP)["sweep"], 2)
    assert not problems
    names = ("npid", "dobc", "mpc")

    def report(factor: float) -> dict:
        return {"arm": "glasgow_2link", "samples": 8, "seed": 11, "duration": 8.0 * factor,
                  "controllers": list(names), "vary": {}, "criteria": [c.label() for c in spec.criteria],
                  "results": summarize(_synthetic(factor), spec, names, 2)}

    base = sweep_json(report(1.0))
    assert sweep_json(report(1 + 1e-12)) == base == sweep_json(report(1 - 1e-12))
    assert SWEEP_DIGITS == 6
    doc = jsonio.loads(base)
    assert doc["_precision"] == "6 significant digits"
    npid = doc["results"]["npid"]["percentiles"]["rms_error"][0]
    assert npid["max"] == 0.0359  # (1 + 0.37 * 7) * 1e-2, at 6 significant digits
    assert npid["p50"] == 0.02295  # the median of the eight samples: (1 + 0.37 * 3.5) * 1e-2
    sse = doc["results"]["dobc"]["percentiles"]["steady_state_error"][1]
    assert sse["p50"] is None and sse["p50_undefined"] == "no finished run of dobc gave this figure"
    mpc = doc["results"]["mpc"]
    assert mpc["failed_runs"] == 8 and mpc["worst"]["value"] is None
    assert mpc["worst"]["value_undefined"] == "the run failed: mpc: the controller step returned 1 at t = 3 s"
    assert doc["results"]["dobc"]["worst"]["value_undefined"] == "steady_state_error undefined in this run"
    assert jsonio.loads(jsonio.dumps(sweep_data(report(1.0)))) == doc  # summary.md's data is the JSON's
    md = summary_markdown("glasgow_2link", sweep_data(report(1.0)))
    assert "| dobc | steady_state_error | 2 | n/a | n/a | n/a | n/a |" in md
    assert md.index("| npid | steady_state_error |") < md.index("| dobc | steady_state_error |")  # the arm's order


def test_sweep_with_the_implicit_observer_and_a_reference_from_the_pose(tmp_path):
    """Issue 20 item 7: derive sweep --observer implicit, and [simulation] reference_start =
    "measured" honoured by every sample and written into the worst sample's arm file, which
    derive simulate --observer implicit reruns to the reported figure."""
    sweep = SWEEP.replace("start = [0.0, 1.0]", 'start = [0.0, 1.0]\ninitial_theta = [0.4, -0.3]\n'
                          'reference_start = "measured"').replace("samples = 8", "samples = 2") \
        .replace("duration = 8.0", "duration = 3.0").replace('controllers = ["mpc", "dobc", "npid"]',
                                                             'controllers = ["dobc"]')
    arm = _arm(tmp_path, sweep)
    out, js = _sweep(tmp_path, arm, "implicit", "--workers", "1", "--observer", "implicit")
    data = jsonio.loads(js)
    assert data["observer"] == "implicit" and "the implicit observer step" in (out / "summary.md").read_text()
    worst = data["results"]["dobc"]["worst"]
    text = (out / worst["file"]).read_text()
    assert text.startswith("# generated by derive sweep: the worst sample, rerun with derive simulate --observer "
                           "implicit;") and 'reference_start = "measured"' in text
    rerun = tmp_path / "rerun.json"
    assert main(["simulate", str(out / worst["file"]), "--controllers", "dobc", "--observer", "implicit",
                 "--out", str(tmp_path / "rerun"), "--json", str(rerun)]) == 0
    links = jsonio.loads(rerun.read_text())["controllers"]["dobc"]["links"]
    assert max(link[worst["metric"]] for link in links) == pytest.approx(worst["value"], rel=1e-5)
    assert max(link["max_error"] for link in links) < 0.3   # from the pose: no 0.4 rad step at t = 0
