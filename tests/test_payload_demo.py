"""Issue 38, "How it is shown": a UR10e-like and an ABB IRB 120-like arm, each with the starter file of
``derive init <urdf> --tip <flange> --payload <rated>`` (tests/data/urdf/payload/, README there), simulated on
derive's plant and on MuJoCo with payloads of 0, half and the full rated mass at a centre of mass 0.1 m off
the flange axis ([0.1, 0, 0] in the tip link's frame, inside the [payload] ball of 0.15 m).

The goal asserted: every observer form (DOBC, NPID, MOM) tracks, its largest per-joint RMS error below
0.01 rad, no input saturated (the metrics' saturated_time is 0), exit 0.

What the starter files say they hold (their [payload] comments, derive.control.payload.design, at the worst
centre of mass of the 0.15 m ball and the speed box): UR10 DOBC/NPID 14.6 kg, MOM 18.9 kg of 12.5 kg at a
20 us sample time (it holds the range); IRB 120-like DOBC/NPID 3.07 kg, MOM 6.42 kg of 3 kg at 20 us on a
speed box of 0.269 x its velocity limits (on the whole box 1.35 kg: its wrist's own inertia is 9e-5 kg m^2,
the payload's up to 792 times that, and the box's corner has a slow gyroscopic mode). The runs here, at
0.1 m off the axis and the experiment's speeds, track on both arms at every payload up to the rated one
(docs/guides/payload.md).

The fast variant runs the starter experiment compressed (every joint's pulse starting 1 s after the
previous one, 8 s in all: every joint moves), about 15-25 s CPU a run, most of it deriving, compiling the
loop and drawing the figures, not simulating; the loaded cases (known failures) and the 30 s starter
experiment itself are marked slow.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from derive.cli import main

DATA = Path(__file__).resolve().parent / "data" / "urdf"
ARMS = {   # name: (starter file, URDF, rated payload [kg])
    "ur10": (DATA / "payload" / "ur10.toml", DATA / "corpus" / "ur10.urdf", 12.5),
    "irb120_like": (DATA / "payload" / "irb120_like.toml", DATA / "payload" / "irb120_like.urdf", 3.0),
}
FORMS = ("dobc", "npid", "mom")
OFF_AXIS = [0.1, 0.0, 0.0]    # m, tip link's frame: 0.1 m off the flange axis (the tip frames' z)
RMS_MAX = 0.01                # rad
COMPRESSED = 'start = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]\n'


def arm_file(folder: Path, arm: str, mass: float, extra: str = "") -> Path:
    """The arm's starter file in ``folder`` (its URDF beside it) with ``payload_mass = mass`` at OFF_AXIS and
    ``extra`` lines in its [simulation] table."""
    toml, urdf, _ = ARMS[arm]
    shutil.copy(urdf, folder / urdf.name)
    text = toml.read_text().replace(f'urdf = "../corpus/{urdf.name}"', f'urdf = "{urdf.name}"')
    lines = f"payload_mass = {mass!r}\npayload_com = {OFF_AXIS!r}\n{extra}"
    assert text.count("\n[simulation]\n") == 1
    path = folder / f"{arm}_{mass:g}.toml"
    path.write_text(text.replace("\n[simulation]\n", "\n[simulation]\n" + lines))
    return path


def worst(metrics: dict) -> dict[str, tuple[float, float]]:
    """form -> (largest per-joint RMS error [rad], largest saturated time [s])."""
    return {f: (max(link["rms_error"] for link in metrics["controllers"][f]["links"]),
                max(link["saturated_time"] for link in metrics["controllers"][f]["links"])) for f in FORMS}


def run(tmp_path: Path, arm: str, plant: str, mass: float, extra: str, duration: float | None) -> dict:
    path = arm_file(tmp_path, arm, mass, extra)
    out = tmp_path / "out"
    args = ["simulate", str(path), "--plant", plant, "--controllers", ",".join(FORMS), "--out", str(out),
            "--json", str(out / "metrics.json")]
    code = main(args + (["--duration", str(duration)] if duration else []))
    assert code == 0, f"derive {' '.join(args)}: exit {code}"
    return worst(json.loads((out / "metrics.json").read_text()))


def check(result: dict, label: str) -> None:
    bad = {f: r for f, r in result.items() if not (r[0] < RMS_MAX and r[1] == 0.0)}
    assert not bad, (f"{label}: forms that do not track (largest per-joint RMS error [rad], saturated time [s]): "
                     f"{bad}; expected RMS < {RMS_MAX} rad and no saturation")


def rated(arm: str, fraction: float) -> float:
    return ARMS[arm][2] * fraction


CASES = [pytest.param(arm, fraction, id=f"{arm}-{fraction:g}") for arm in ARMS for fraction in (0.0, 0.5, 1.0)]


# The demonstration runs in make fuzz (slow): make test holds the statement it rests on to its truth
# (tests/test_payload_limit.py) and MuJoCo's payload to derive's plant (tests/test_payload_plant.py)
EXPERIMENTS = {   # id: (lines added to [simulation], duration [s] or None: the file's 30 s)
    "compressed": (COMPRESSED, 8.0),
    "starter": ("", None),
}


@pytest.mark.slow
@pytest.mark.parametrize("experiment", list(EXPERIMENTS))
@pytest.mark.parametrize("plant", ["derive", "mujoco"])
@pytest.mark.parametrize("arm, fraction", CASES)
def test_starter_tracks_the_payload(tmp_path: Path, arm: str, fraction: float, plant: str, experiment: str) -> None:
    """The compressed starter experiment (every joint's pulse 1 s after the previous, 8 s) and the starter
    experiment as the file states it (30 s): every form tracks (RMS < 0.01 rad, no saturation, exit 0)."""
    if plant == "mujoco":
        pytest.importorskip("mujoco")
    mass = rated(arm, fraction)
    extra, duration = EXPERIMENTS[experiment]
    check(run(tmp_path, arm, plant, mass, extra, duration),
          f"{arm}, {plant}'s plant, {mass:g} kg at {OFF_AXIS} m, {experiment} experiment")


SWEEP = """
[sweep]
samples = 64
seed = 38
controllers = ["dobc", "npid", "mom"]
duration = {duration}
[sweep.vary]
payload_mass = {{ distribution = "uniform", low = 0.0, high = {mass} }}
payload_com = {{ distribution = "uniform", low = -0.0866, high = 0.0866 }}   # each component: the cube inside the 0.15 m ball
[[sweep.criterion]]
metric = "rms_error"
max = 0.01
[[sweep.criterion]]
metric = "saturated_time"
max = 0.0
"""


def sweep(tmp_path: Path, arm: str, duration: float, extra: str) -> tuple[bytes, bytes, dict]:
    """sweep.json of 64 payloads on MuJoCo with 1 and 2 workers (bytes each) and the parsed first."""
    path = arm_file(tmp_path, arm, 0.0, extra)
    path.write_text(path.read_text() + SWEEP.format(duration=duration, mass=ARMS[arm][2]))
    out = []
    for workers in (1, 2):
        folder = tmp_path / f"w{workers}"
        code = main(["sweep", str(path), "--plant", "mujoco", "--workers", str(workers), "--out", str(folder)])
        assert code in (0, 1), f"derive sweep --workers {workers}: exit {code}"
        out.append((folder / "sweep.json").read_bytes())
    return out[0], out[1], json.loads(out[0])


@pytest.mark.slow
def test_payload_sweep_is_reproducible_and_tracks(tmp_path: Path) -> None:
    """64 payloads (mass uniform 0..rated, centre of mass in the [payload] ball) on MuJoCo, the compressed
    experiment on the IRB 120-like: sweep.json byte-identical with 1 and 2 workers, and every sample meets
    rms_error <= 0.01 rad and no saturation, every form (one sweep pair: each is 64 x 3 runs of 400,000 steps)."""
    pytest.importorskip("mujoco")
    one, two, result = sweep(tmp_path, "irb120_like", 8.0, COMPRESSED)
    assert one == two, "sweep.json differs between 1 and 2 workers"
    fractions = {f: result["results"][f]["pass_fraction"]["all criteria"] for f in FORMS}
    assert all(x == 1.0 for x in fractions.values()), f"pass fractions of 64 payloads: {fractions}"


@pytest.mark.slow
def test_nominal_starter_loses_the_rated_payload(tmp_path: Path) -> None:
    """The issue's symptom, and what the design changes: the UR10's starter written without --payload states a
    payload limit far below 12.5 kg (its `derive show` line), and with 12.5 kg 0.1 m off the flange axis on
    derive's plant at least one observer form does not track (largest per-joint RMS error >= 0.01 rad or
    saturation), where the designed file's every form does (test_starter_tracks_the_payload)."""
    from derive.control.payload.text import stated
    from derive.control.pipeline import derive
    from derive.model.payload import PayloadRange
    from derive.model.spec import load_arm

    urdf = ARMS["ur10"][1]
    shutil.copy(urdf, tmp_path / urdf.name)
    nominal = tmp_path / "ur10_nominal.toml"
    assert main(["init", str(tmp_path / urdf.name), "--base", "base_link", "--tip", "tool0", "--out", str(nominal)]) == 0
    arm = load_arm(nominal)
    from dataclasses import replace
    held = stated(derive(replace(arm, payload=PayloadRange(mass=12.5, com=(0.0, 0.0, 0.0), com_radius=0.15))))
    assert max(held[f].limit for f in FORMS) < 12.5
    text = nominal.read_text()
    path = tmp_path / "loaded.toml"
    path.write_text(text.replace("\n[simulation]\n", f"\n[simulation]\npayload_mass = 12.5\npayload_com = {OFF_AXIS!r}\n"
                                 + COMPRESSED))
    out = tmp_path / "out"
    code = main(["simulate", str(path), "--controllers", ",".join(FORMS), "--out", str(out), "--duration", "8.0",
                 "--json", str(out / "metrics.json")])
    assert code in (0, 1)
    result = worst(json.loads((out / "metrics.json").read_text()))
    assert any(not (rms < RMS_MAX and sat == 0.0) for rms, sat in result.values()), result
