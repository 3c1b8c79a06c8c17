"""derive simulate's cache (derive.sim.cache, issue 23): the derivation, the compiled loop and
the figures kept per arm file, the files it reads, the options and derive's code; the results
of a run from the cache are the bytes of a run without it; a bad entry is rebuilt."""
from __future__ import annotations

import pickle
from pathlib import Path

import pytest

from derive.cli import main
from derive.model.spec import load_arm
from derive.sim import cache as simcache
from derive.sim.cache import SimCache, entry_key

ARGS = ["simulate", "--duration", "2"]   # the default arm, its four controllers, 2 s each


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _simulate(out: Path, *extra: str) -> None:
    assert main([*ARGS, "--out", str(out), *extra]) == 0


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The default arm simulated without the cache, then twice with it (cold, warm): the
    folders, the cache folder and each run's standard error."""
    import contextlib
    import io
    import os

    tmp = tmp_path_factory.mktemp("sim")
    old = os.environ.get(simcache.ENV)
    os.environ[simcache.ENV] = str(tmp / "cache")
    err = {}
    try:
        for name, extra in (("none", ("--no-cache",)), ("cold", ()), ("warm", ())):
            with contextlib.redirect_stderr(io.StringIO()) as stream:
                _simulate(tmp / name, *extra)
            err[name] = stream.getvalue()
            if name == "none":
                assert not (tmp / "cache").exists(), "--no-cache keeps nothing"
    finally:
        os.environ.pop(simcache.ENV) if old is None else os.environ.__setitem__(simcache.ENV, old)
    return tmp, err


def test_a_run_from_the_cache_writes_the_bytes_of_a_run_without_it(runs):
    tmp, err = runs
    cache_dir = tmp / "cache"
    assert "from the cache" not in err["none"] + err["cold"] and "from the cache" in err["warm"]
    entries = list((cache_dir / "simulate").glob("*.pickle"))
    assert len(entries) == 1 and len(list((cache_dir / "figures").glob("*.png"))) == 3
    kept = pickle.loads(entries[0].read_bytes())["values"]
    assert {"derivation", "loop", ("too_slow", ("dobc", "mom", "mpc", "npid"))} <= set(kept)
    none, cold, warm = (_tree(tmp / k) for k in ("none", "cold", "warm"))
    assert set(none) == {"MANIFEST.json", "metrics.md", "link1.png", "link2.png", "tracking_error.png"}
    assert none == cold == warm


def test_an_entry_cut_short_and_a_cut_figure_are_ignored_and_rebuilt(runs, tmp_path, monkeypatch):
    import shutil

    tmp, _ = runs
    cache_dir = tmp_path / "cache"
    shutil.copytree(tmp / "cache", cache_dir)
    monkeypatch.setenv(simcache.ENV, str(cache_dir))
    entry = next((cache_dir / "simulate").glob("*.pickle"))
    whole = entry.read_bytes()
    entry.write_bytes(whole[: len(whole) // 2])   # as a writer killed half-way would leave it without os.replace
    figure = next((cache_dir / "figures").glob("*.png"))
    figure.write_bytes(figure.read_bytes()[:100])
    _simulate(tmp_path / "again")
    assert _tree(tmp_path / "again") == _tree(tmp / "none")
    assert pickle.loads(entry.read_bytes())["values"].keys() == pickle.loads(whole)["values"].keys()
    assert figure.read_bytes().endswith(b"IEND\xaeB`\x82")
    assert not [p for p in cache_dir.rglob("*") if p.name.endswith(".part")]   # no temporary file left


@pytest.mark.parametrize("damaged", [b"", b"not a pickle", pickle.dumps({"format": -1, "key": "k", "values": {}}),
                                     pickle.dumps({"format": simcache.FORMAT, "key": "another", "values": {"x": 1}}),
                                     pickle.dumps(["a list"])])
def test_an_unreadable_entry_or_another_keys_is_a_miss(tmp_path, damaged):
    (tmp_path / "simulate").mkdir()
    (tmp_path / "simulate" / "k.pickle").write_bytes(damaged)
    c = SimCache(tmp_path, "k")
    assert not c.hit and c.get("x", lambda: 2) == 2
    c.save()
    assert SimCache(tmp_path, "k").data == {"x": 2}


def test_the_key_follows_the_arm_file_the_urdf_it_reads_the_options_and_derives_code(tmp_path, monkeypatch):
    arm_file = tmp_path / "arm.toml"
    source = Path(__file__).resolve().parent / "data" / "urdf" / "double_pendulum.toml"
    text = source.read_text()
    arm_file.write_text(text)
    import tomllib

    robot = tomllib.loads(text)["arm"]["urdf"]
    (tmp_path / robot).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / robot).write_bytes((source.parent / robot).read_bytes())
    options = {"observer": "explicit", "plants": ("derive",), "friction": "file"}
    base = entry_key(load_arm(arm_file), options)
    assert entry_key(load_arm(arm_file), options) == base    # deterministic
    assert entry_key(load_arm(arm_file), {**options, "observer": "implicit"}) != base
    (tmp_path / robot).write_bytes((tmp_path / robot).read_bytes() + b"\n<!-- edited -->\n")
    assert entry_key(load_arm(arm_file), options) != base    # the URDF's bytes count, not only the arm file's
    (tmp_path / robot).write_bytes((source.parent / robot).read_bytes())
    arm_file.write_text(text + "\n# a comment\n")
    assert entry_key(load_arm(arm_file), options) != base
    arm_file.write_text(text)
    monkeypatch.setattr(simcache, "code_fingerprint", lambda: "another derive")
    assert entry_key(load_arm(arm_file), options) != base    # a new derive version (or edited code) misses


def test_the_cache_folder_is_platformdirs_user_cache_dir_unless_the_variable_is_set(monkeypatch, tmp_path):
    from platformdirs import user_cache_dir

    monkeypatch.delenv(simcache.ENV, raising=False)
    assert simcache.cache_dir() == Path(user_cache_dir("derive"))
    monkeypatch.setenv(simcache.ENV, str(tmp_path))
    assert simcache.cache_dir() == tmp_path


def test_a_failed_write_leaves_no_entry_and_no_temporary_file(tmp_path, monkeypatch):
    import os

    def refuse(src, dst):
        raise OSError(28, "No space left on device")

    c = SimCache(tmp_path, "k")
    assert c.get("x", lambda: 41) == 41 and c.get("x", lambda: 0) == 41
    monkeypatch.setattr(os, "replace", refuse)
    c.save()
    monkeypatch.undo()
    assert [p.name for p in (tmp_path / "simulate").iterdir()] == []
    c.save()   # still dirty: written now
    assert SimCache(tmp_path, "k").data == {"x": 41} and SimCache(tmp_path, "other").data == {}
