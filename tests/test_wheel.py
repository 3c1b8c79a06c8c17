"""The wheel generates, compiles and self-tests without the repository (issue 10, item 8).

A wheel built from the repository installed and ran ``derive show``, but ``derive
generate`` died with jinja2's TemplateNotFound: templates/ (at the top of the
repository) was not in it. Here, as ``python -m build`` does, an sdist is built from a
copy of the source tree and the wheel from the sdist (setuptools' build_meta and
``pip wheel --no-build-isolation``, with the setuptools the test extras install: no
network); the wheel's listing is checked for every file derive reads at run time (templates,
packaged arms, embedded board files, FMU headers), and it is installed by pip, offline
(``--no-index``), into a fresh virtual environment whose only other packages are the
current environment's dependencies (linked in a folder without derive itself, so the
dependency pins are resolved for real). There, from an empty folder, ``derive --version``
names the version and ``derive generate`` writes the default arm, whose C compiles and
passes its own self-test.

``make fuzz`` (marker ``slow``, about two minutes) also installs the wheel as a user without
network would: ``pip install --no-index --find-links WHEELHOUSE derive`` into a bare virtual
environment, every dependency resolved by pip from a local folder of wheels (the
environment's installed distributions repacked by pypa's ``wheel pack``; urdf-parser-py,
published as an sdist only, among them), then ``derive --version`` and ``derive generate``.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from importlib import metadata
from pathlib import Path

import pytest

from .cbuild import STRICT

ROOT = Path(__file__).resolve().parent.parent
SKIP = {".git", ".venv", "build", "dist", "generated", "__pycache__", ".pytest_cache", ".hypothesis"}


def _run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, **kw)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))}\n{proc.stdout}\n{proc.stderr}"
    return proc


def _source_copy(dest: Path) -> Path:
    """The source tree without build products, environments or generated outputs."""
    shutil.copytree(ROOT, dest, ignore=lambda d, names: [n for n in names if n in SKIP or n.endswith(".egg-info")])
    return dest


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("wheel")
    src = _source_copy(tmp / "src")
    # as `python -m build` does: the sdist first, the wheel from the unpacked sdist
    sdist = _run([sys.executable, "-c", "import sys; from setuptools import build_meta; "
                  "print(build_meta.build_sdist(sys.argv[1]))", str(tmp / "sdist")], cwd=src).stdout.split()[-1]
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-index", "--no-build-isolation",
          "-w", str(tmp / "dist"), str(tmp / "sdist" / sdist)])
    wheels = list((tmp / "dist").glob("derive-*.whl"))
    assert len(wheels) == 1, wheels
    return wheels[0]


def test_the_wheel_holds_every_file_derive_reads_at_run_time(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    templates = {f"derive/templates/{p.relative_to(ROOT / 'templates').as_posix()}"
                 for p in (ROOT / "templates").rglob("*") if p.is_file()}
    arms = {f"derive/model/arms/{p.name}" for p in (ROOT / "derive" / "model" / "arms").glob("*.toml")}
    board = {f"derive/embedded/board/{p.name}" for p in (ROOT / "derive" / "embedded" / "board").iterdir()
             if p.suffix in (".c", ".ld")}
    fmu = {f"derive/fmu/headers/{p.relative_to(ROOT / 'derive' / 'fmu' / 'headers').as_posix()}"
           for p in (ROOT / "derive" / "fmu" / "headers").rglob("*") if p.is_file()}
    assert len(templates) >= 19 and "derive/templates/c/arm.h.jinja" in templates
    assert arms and board and fmu
    missing = sorted((templates | arms | board | fmu) - names)
    assert not missing, missing


WHEELHOUSE = Path(os.environ.get("DERIVE_WHEELHOUSE", ROOT / "build" / "wheelhouse"))
BESIDE = ("numpy", "sympy")   # installed first, from WHEELHOUSE (scripts/wheelhouse.sh)


def _dependencies_only(tmp: Path, leave_out: tuple[str, ...] = ()) -> Path:
    """A folder of links to the current environment's installed distributions, derive's
    own (editable) install left out, and the top-level names starting with one of ``leave_out``."""
    folder = tmp / "deps"
    folder.mkdir()
    seen = set()
    for key in ("purelib", "platlib"):
        site = Path(sysconfig.get_paths()[key])
        if site in seen:
            continue
        seen.add(site)
        for entry in site.iterdir():
            name = entry.name.lower()
            if name.startswith(("derive", "__editable__", "_derive", *leave_out)) or entry.suffix == ".pth":
                continue
            if not (folder / entry.name).exists():
                (folder / entry.name).symlink_to(entry)
    return folder


def _constraint(name: str) -> str:
    """The version constraints.txt pins ``name`` to."""
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        if line.lower().startswith(f"{name}=="):
            return line.split("==", 1)[1].strip()
    raise AssertionError(f"constraints.txt pins no {name}")


def _beside_wheels() -> dict[str, Path]:
    """The numpy and sympy wheels of the wheelhouse ``make wheelhouse`` prepares."""
    found = {name: sorted(WHEELHOUSE.glob(f"{name}-*.whl")) for name in BESIDE}
    missing = [name for name, wheels in found.items() if len(wheels) != 1]
    if missing:
        message = (f"no single {' and '.join(missing)} wheel in {WHEELHOUSE}: run `make wheelhouse` "
                   "(scripts/wheelhouse.sh; make test does)")
        if os.environ.get("DERIVE_REQUIRE_PINNED"):
            pytest.fail(message)
        pytest.skip(message)
    return {name: wheels[0] for name, wheels in found.items()}


def test_the_wheel_installs_offline_beside_an_older_numpy_and_generates_compiles_and_self_tests(wheel, tmp_path):
    """Issue 23: pyproject.toml states ranges, so installing derive keeps the numpy and sympy a user
    has. A fresh virtual environment first gets numpy 2.0.2 (older than constraints.txt's) and the
    newest sympy published (scripts/wheelhouse.sh), installed offline from the wheelhouse; derive's
    other dependencies are the current environment's (linked in, numpy and sympy left out); then pip
    installs the wheel (--no-index: a pin it cannot meet from what is there fails the install) and
    must leave numpy and sympy as they were. There, from an empty folder, ``derive --version`` names
    the version and ``derive generate`` writes the default arm, whose C compiles and passes its own
    self-test (the reference values are computed in that environment, under numpy 2.0.2)."""
    from packaging.version import Version

    beside = _beside_wheels()
    versions = {name: whl.name.split("-")[1] for name, whl in beside.items()}
    assert Version("2") <= Version(versions["numpy"]) < Version(_constraint("numpy")), versions
    assert Version(versions["sympy"]) >= Version(_constraint("sympy")), versions
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    python = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PIP_"))}
    env["PIP_NO_INDEX"] = "1"  # no network, no index: the dependencies are there already
    env["PIP_CONFIG_FILE"] = os.devnull  # nor the machine's pip configuration (find-links, constraints)
    pip = [sys.executable, "-m", "pip", "--python", str(python)]
    _run([*pip, "install", "--no-index", "--no-deps", "--no-compile", "--no-cache-dir", *map(str, beside.values())],
         env=env)
    site = Path(_run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    (site / "dependencies.pth").write_text(str(_dependencies_only(tmp_path, (*BESIDE, "isympy"))) + "\n")
    _run([*pip, "install", "--no-index", "--no-cache-dir", str(wheel)], env=env)
    work = tmp_path / "empty"
    work.mkdir()
    derive = venv / "bin" / "derive"
    found = _run([str(python), "-c", "import derive, numpy, sympy; print(derive.__file__, numpy.__file__, "
                  "sympy.__file__, numpy.__version__, sympy.__version__)"], cwd=work, env=env).stdout.split()
    assert all(f.startswith(str(venv)) for f in found[:3]), found  # the wheel's derive, the venv's numpy and sympy
    assert found[3:] == [versions["numpy"], versions["sympy"]], (found, versions)  # kept, not replaced
    version = _run([str(derive), "--version"], cwd=work, env=env).stdout
    assert version.strip() == f"derive {metadata.version('derive')}"
    _run([str(derive), "generate", "--out", "out"], cwd=work, env=env)
    c_dir = work / "out" / "glasgow_2link" / "c"
    exe = work / "selftest"
    _run(["gcc", *STRICT, "-O2", f"-I{c_dir}", *(str(c_dir / f) for f in
          ("glasgow_2link.c", "glasgow_2link_kernels.c", "glasgow_2link_selftest.c")), "-lm", "-o", str(exe)])
    out = _run([str(exe)]).stdout
    assert re.search(r"^(\d+) passed, 0 failed$", out, re.M), out
    manifest = json.loads((work / "out" / "glasgow_2link" / "MANIFEST.json").read_text())
    assert manifest["versions"]["numpy"] == versions["numpy"], manifest["versions"]  # made under the older numpy


def test_the_wheel_states_ranges_that_admit_other_numpy_and_sympy_releases(wheel):
    """The wheel's Requires-Dist (what pip resolves): a range for each dependency, never a pin;
    numpy 2.0.2 and every later 2.x, and sympy releases after constraints.txt's, admitted (no
    upper bound; pyproject.toml names one only where a known break exists)."""
    from packaging.requirements import Requirement

    with zipfile.ZipFile(wheel) as z:
        meta = z.read(next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))).decode()
    reqs = [Requirement(line.split(":", 1)[1].strip()) for line in meta.splitlines()
            if line.startswith("Requires-Dist:")]
    runtime = {r.name.lower(): r.specifier for r in reqs if r.marker is None}
    assert not [f"{n}{s}" for n, s in runtime.items() if any(spec.operator in ("==", "===") for spec in s)]
    for name, later in (("numpy", ("2.0.2", "2.4.6", "2.9.0")), ("sympy", ("1.14.0", "1.15.0", "2.0.0")),
                        ("casadi", ("3.8.2", "3.9.0")), ("jinja2", ("3.1.6", "3.2.0")),
                        ("python-flint", ("0.9.0", "0.10.0")), ("platformdirs", ("4.14.9", "5.0.0"))):
        assert all(runtime[name].contains(v) for v in later), (name, runtime[name])
    assert not runtime["numpy"].contains("1.26.4"), runtime["numpy"]   # derive needs numpy 2


def _runtime_distributions() -> list[metadata.Distribution]:
    """derive's runtime dependencies and theirs, as installed here (markers evaluated
    without extras: what ``pip install derive`` resolves)."""
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    found: dict[str, metadata.Distribution] = {}
    todo = [Requirement(r) for r in metadata.requires("derive") or []]
    while todo:
        req = todo.pop()
        if req.marker is not None and not req.marker.evaluate({"extra": ""}):
            continue
        name = canonicalize_name(req.name)
        if name not in found:
            found[name] = metadata.distribution(req.name)
            todo += [Requirement(r) for r in found[name].requires or []]
    return [found[k] for k in sorted(found)]


def _repack(dist: metadata.Distribution, staging: Path, wheelhouse: Path) -> None:
    """A wheel of an installed distribution, packed by pypa's ``wheel pack`` from the files
    its RECORD lists (an installed distribution is an unpacked wheel; console scripts come
    back from entry_points.txt on install). urdf-parser-py is published as an sdist only:
    this is how its wheel gets into the wheelhouse without a network."""
    root = staging / f"{dist.metadata['Name']}-{dist.version}"
    info = None
    for f in dist.files or []:
        parts = f.parts
        if parts[0] == ".." or "__pycache__" in parts:
            continue  # scripts in bin/ (regenerated), bytecode (recompiled)
        if parts[0].endswith(".dist-info"):
            info = parts[0]
            if parts[-1] in ("RECORD", "INSTALLER", "REQUESTED", "direct_url.json"):
                continue
        source = Path(dist.locate_file(f))
        target = root / f
        target.parent.mkdir(parents=True, exist_ok=True)
        os.link(source, target) if source.stat().st_dev == staging.stat().st_dev else shutil.copy2(source, target)
    assert info is not None and (root / info / "WHEEL").is_file(), (dist.metadata["Name"], info)
    _run([sys.executable, "-m", "wheel", "pack", "-d", str(wheelhouse), str(root)])


@pytest.mark.slow
def test_the_wheel_installs_from_a_local_wheelhouse_with_no_index_and_generates(wheel, tmp_path):
    """``pip install --no-index --find-links WHEELHOUSE derive`` into a fresh venv: pip
    resolves every dependency pin for real, from wheels only (the environment's installed
    distributions repacked, urdf-parser-py's among them); then ``derive --version`` and
    ``derive generate`` of the default arm run from the installed wheel (make fuzz; ~2 min)."""
    wheelhouse, staging = tmp_path / "wheelhouse", tmp_path / "staging"
    wheelhouse.mkdir()
    staging.mkdir()
    shutil.copy2(wheel, wheelhouse)
    dists = _runtime_distributions()
    assert {"casadi", "sympy", "urdf-parser-py", "jinja2"} <= {d.metadata["Name"].lower().replace("_", "-")
                                                            for d in dists}
    for dist in dists:
        _repack(dist, staging, wheelhouse)
    assert len(list(wheelhouse.glob("*.whl"))) == len(dists) + 1
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    python = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PIP_"))}
    env["PIP_CONFIG_FILE"] = os.devnull  # only the wheelhouse: not the machine's find-links or constraints
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-index", "--no-cache-dir",
          "--find-links", str(wheelhouse), "derive"], env=env)
    frozen = _run([sys.executable, "-m", "pip", "--python", str(python), "list", "--format=freeze"], env=env).stdout
    assert f"derive=={metadata.version('derive')}" in frozen.split() and "urdf_parser_py==0.0.4" in frozen.replace(
        "-", "_").split(), frozen
    work = tmp_path / "empty"
    work.mkdir()
    where = _run([str(python), "-c", "import derive, casadi; print(derive.__file__, casadi.__file__)"],
                 cwd=work, env=env).stdout.split()
    assert all(w.startswith(str(venv)) for w in where), where  # installed from the wheelhouse, nothing else
    version = _run([str(venv / "bin" / "derive"), "--version"], cwd=work, env=env).stdout
    assert version.strip() == f"derive {metadata.version('derive')}"
    _run([str(venv / "bin" / "derive"), "generate", "--out", "out"], cwd=work, env=env)
    c_dir = work / "out" / "glasgow_2link" / "c"
    for name in ("glasgow_2link.h", "glasgow_2link.c", "glasgow_2link_kernels.c", "glasgow_2link_plant.c"):
        assert (c_dir / name).read_bytes() == (ROOT / "generated" / "glasgow_2link" / "c" / name).read_bytes(), name
