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
"""
from __future__ import annotations

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


def _dependencies_only(tmp: Path) -> Path:
    """A folder of links to the current environment's installed distributions, derive's
    own (editable) install left out."""
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
            if name.startswith(("derive", "__editable__", "_derive")) or entry.suffix == ".pth":
                continue
            if not (folder / entry.name).exists():
                (folder / entry.name).symlink_to(entry)
    return folder


def test_the_wheel_installs_offline_and_generates_compiles_and_self_tests(wheel, tmp_path):
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    python = venv / "bin" / "python"
    site = Path(_run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    (site / "dependencies.pth").write_text(str(_dependencies_only(tmp_path)) + "\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PIP_"))}
    env["PIP_NO_INDEX"] = "1"  # no network, no index: the dependencies are there already
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-index", "--no-cache-dir",
          str(wheel)], env=env)
    work = tmp_path / "empty"
    work.mkdir()
    derive = venv / "bin" / "derive"
    where = _run([str(python), "-c", "import derive; print(derive.__file__)"], cwd=work, env=env).stdout
    assert where.startswith(str(venv)), where  # the wheel's derive, not the repository's
    version = _run([str(derive), "--version"], cwd=work, env=env).stdout
    assert version.strip() == f"derive {metadata.version('derive')}"
    _run([str(derive), "generate", "--out", "out"], cwd=work, env=env)
    c_dir = work / "out" / "glasgow_2link" / "c"
    exe = work / "selftest"
    _run(["gcc", *STRICT, "-O2", f"-I{c_dir}", *(str(c_dir / f) for f in
          ("glasgow_2link.c", "glasgow_2link_kernels.c", "glasgow_2link_selftest.c")), "-lm", "-o", str(exe)])
    out = _run([str(exe)]).stdout
    assert re.search(r"^(\d+) passed, 0 failed$", out, re.M), out
    # the generated files are the committed ones: the wheel's templates are the repository's
    for name in ("glasgow_2link.h", "glasgow_2link.c", "glasgow_2link_kernels.c"):
        assert (c_dir / name).read_bytes() == (ROOT / "generated" / "glasgow_2link" / "c" / name).read_bytes(), name
