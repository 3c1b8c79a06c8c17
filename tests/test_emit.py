"""The one writer keeps what derive did not write (issue 15.1) and stays all-or-nothing.

``derive generate my3.toml --out gen_d`` used to replace the whole folder and so
deleted the user's ``gen_d/my3/c/build/``. derive now owns exactly the files its
MANIFEST.json lists: those are replaced as one set, everything else stays.
"""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import pytest

import derive
from derive.codegen import emit
from derive.codegen.emit import write_file, write_tree
from derive.codegen.files import generate_files
from derive.errors import EmitError


def _manifest(*paths: str) -> str:
    return json.dumps({"files": sorted(paths)}) + "\n"


def _set(**files: str) -> dict[str, str]:
    """A file set with its manifest: keyword a__b means path a/b."""
    out = {k.replace("__", "/"): v for k, v in files.items()}
    return {"MANIFEST.json": _manifest(*out), **out}


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_regenerating_keeps_a_build_folder_and_a_loose_file(tmp_path, paper):
    """The instance of the issue: a CMake build folder in c/ and a note beside the code survive,
    unmoved (same inode, same modification time); derive's files are the new ones."""
    target = tmp_path / "glasgow_2link"
    first = generate_files(paper, b"first arm file")
    assert write_tree(target, first).kept == ()
    build = target / "c" / "build"
    (build / "CMakeFiles").mkdir(parents=True)
    (build / "CMakeCache.txt").write_text("CMAKE_BUILD_TYPE:STRING=Release\n")
    (build / "CMakeFiles" / "x.o").write_bytes(b"\x7fELF")
    (target / "notes.txt").write_text("my tuning notes\n")
    inode, mtime = build.stat().st_ino, (build / "CMakeCache.txt").stat().st_mtime_ns
    second = generate_files(paper, b"second arm file")
    done = write_tree(target, second)
    assert done.kept == ("c/build/", "notes.txt") and done.removed == ()
    assert (build / "CMakeCache.txt").read_text() == "CMAKE_BUILD_TYPE:STRING=Release\n"
    assert (build / "CMakeFiles" / "x.o").read_bytes() == b"\x7fELF"
    assert (target / "notes.txt").read_text() == "my tuning notes\n"
    assert build.stat().st_ino == inode and (build / "CMakeCache.txt").stat().st_mtime_ns == mtime
    ours = {k: v for k, v in _tree(target).items() if not k.startswith("c/build/") and k != "notes.txt"}
    assert ours == {k: v.encode() for k, v in second.items()}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["glasgow_2link"]      # no staging left


def test_a_file_derive_did_not_write_in_the_way_is_refused_naming_it(tmp_path):
    target = tmp_path / "out"
    write_tree(target, _set(a="1"))
    (target / "b").write_text("the user's b")
    (target / "sub").write_text("a file where derive will want a folder")
    before = _tree(target)
    with pytest.raises(EmitError, match=r"derive did not write b, sub \(a file where derive needs a folder\) "
                                        r"\(not in MANIFEST.json\) and will not replace it"):
        write_tree(target, _set(a="2", b="2", sub__c="2"))
    assert _tree(target) == before


def test_files_derive_no_longer_writes_are_removed_with_folders_left_empty(tmp_path):
    target = tmp_path / "out"
    write_tree(target, _set(a__x="1", b__y="1", c="1"))
    (target / "b" / "mine.txt").write_text("mine")
    done = write_tree(target, _set(c="2"))
    assert done.removed == ("a/x", "b/y") and done.kept == ("b/",)
    assert _tree(target) == {"MANIFEST.json": _manifest("c").encode(), "b/mine.txt": b"mine", "c": b"2"}
    assert not (target / "a").exists()


@pytest.mark.parametrize("failure", [OSError(28, "No space left on device"), KeyboardInterrupt()],
                         ids=["disk-full", "ctrl-c"])
@pytest.mark.parametrize("at", [1, 3, 5, 6])
def test_a_failure_while_swapping_puts_everything_back(tmp_path, monkeypatch, failure, at):
    """The k-th rename of the swap fails: the previous files, manifest and the user's file are
    back as they were, nothing is left beside the folder."""
    target = tmp_path / "out"
    write_tree(target, _set(a="old", d__x="old", gone="old"))
    (target / "d" / "mine").write_text("mine")
    before = _tree(target)
    real, calls = os.rename, {"n": 0}

    def flaky(src, dst):
        calls["n"] += 1
        if calls["n"] == at:
            raise failure
        return real(src, dst)

    monkeypatch.setattr(emit.os, "rename", flaky)
    with pytest.raises(EmitError if isinstance(failure, OSError) else KeyboardInterrupt):
        write_tree(target, _set(a="new", d__x="new", e__f="new"))
    monkeypatch.undo()
    assert calls["n"] >= at
    assert _tree(target) == before and not (target / "e").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("text, match", [
    ("not json", "expected a JSON object whose \"files\" lists the files derive wrote"),
    ('{"files": "a"}', "expected a JSON object whose"),
    ('{"files": ["../outside"]}', "expected relative paths inside the folder, got '../outside'"),
    ('{"files": ["/etc/passwd"]}', "got '/etc/passwd'"),
])
def test_a_manifest_derive_cannot_read_is_refused(tmp_path, text, match):
    target = tmp_path / "out"
    target.mkdir()
    (target / "MANIFEST.json").write_text(text)
    with pytest.raises(EmitError, match=match):
        write_tree(target, _set(a="1"))
    assert sorted(p.name for p in target.iterdir()) == ["MANIFEST.json"]


def test_a_symbolic_link_on_the_way_is_refused(tmp_path):
    target, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    write_tree(target, _set(a="1"))
    elsewhere.mkdir()
    (target / "c").symlink_to(elsewhere)
    with pytest.raises(EmitError, match=r"derive did not write c \(a symbolic link\)"):
        write_tree(target, _set(a="2", c__x="2"))
    assert list(elsewhere.iterdir()) == []


def test_the_new_manifest_must_list_every_file_written(tmp_path):
    with pytest.raises(ValueError, match="must list exactly the other files written"):
        write_tree(tmp_path / "out", {"MANIFEST.json": _manifest("a"), "a": "1", "b": "1"})
    with pytest.raises(ValueError, match="must list exactly"):
        write_tree(tmp_path / "out", {"a": "1"})
    assert not (tmp_path / "out").exists()


@pytest.fixture
def umask_027():
    old = os.umask(0o027)
    yield
    os.umask(old)


def test_folders_and_files_follow_the_umask(tmp_path, umask_027):
    """A report of derive check was 0600 (mkstemp): every writer now follows the umask."""
    target = tmp_path / "out"
    write_tree(target, _set(a="1"))
    write_tree(target, _set(a="2", sub__b="2"))
    modes = {p: stat.S_IMODE((target / p).stat().st_mode) for p in ("", "a", "sub", "sub/b", "MANIFEST.json")}
    assert modes == {"": 0o750, "a": 0o640, "sub": 0o750, "sub/b": 0o640, "MANIFEST.json": 0o640}
    write_file(tmp_path / "report.md", "x")
    assert stat.S_IMODE((tmp_path / "report.md").stat().st_mode) == 0o640


def test_write_file_failure_is_an_emit_error(tmp_path):
    with pytest.raises(EmitError, match="cannot write"):
        write_file(tmp_path / "missing" / "x.json", "{}")
