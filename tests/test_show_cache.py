"""derive show's cache (derive.cli.show_cache, issue 23: `derive show my3` under 1 s): a second show
of the same inputs prints the same bytes without deriving (no SymPy imported); a changed arm file,
URDF or option is a miss; --no-cache keeps nothing; a refusal is never kept; a bad entry is ignored."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from derive.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _show(tmp_path: Path, *argv: str) -> tuple[int, str, str]:
    """derive show in a fresh interpreter with the cache in tmp_path/cache: (exit code, stdout, stderr)."""
    import os

    env = dict(os.environ, DERIVE_CACHE_DIR=str(tmp_path / "cache"))
    code = "import sys; from derive.cli import main; rc = main(sys.argv[1:]); " \
           "print('sympy imported' if 'sympy' in sys.modules else 'sympy not imported', file=sys.stderr); sys.exit(rc)"
    p = subprocess.run([sys.executable, "-c", code, "show", *argv], capture_output=True, text=True, env=env,
                       cwd=tmp_path)
    return p.returncode, p.stdout, p.stderr


@pytest.fixture
def arm(tmp_path) -> Path:
    path = tmp_path / "arm.toml"
    shutil.copy(ROOT / "derive" / "model" / "arms" / "glasgow_2link.toml", path)
    return path


def test_a_second_show_prints_the_same_bytes_from_the_cache_without_sympy(tmp_path, arm):
    code, cold, err = _show(tmp_path, str(arm))
    assert code == 0 and "sympy imported" in err and "Sample time:" in cold
    assert len(list((tmp_path / "cache" / "show").glob("*.json"))) == 1
    code, warm, err = _show(tmp_path, str(arm))
    assert code == 0 and warm == cold and err.strip() == "sympy not imported"


def test_a_changed_arm_file_or_option_is_a_miss_and_no_cache_keeps_nothing(tmp_path, arm):
    _, before, _ = _show(tmp_path, str(arm))
    arm.write_text(arm.read_text().replace('T2 = "1/1.2"', "T2 = 0.5"))
    code, after, err = _show(tmp_path, str(arm))
    assert code == 0 and "sympy imported" in err and after != before
    code, latex, err = _show(tmp_path, str(arm), "--latex")
    assert code == 0 and "sympy imported" in err and latex.startswith("%")
    entries = sorted((tmp_path / "cache" / "show").glob("*.json"))
    assert len(entries) == 3
    code, again, err = _show(tmp_path, str(arm), "--no-cache")
    assert code == 0 and again == after and "sympy imported" in err
    assert sorted((tmp_path / "cache" / "show").glob("*.json")) == entries


def test_a_refusal_is_never_kept_and_a_bad_entry_is_rebuilt(tmp_path, arm, capsys, monkeypatch):
    bad = tmp_path / "bad.toml"
    bad.write_text("[arm]\nname = 3\n")
    monkeypatch.setenv("DERIVE_CACHE_DIR", str(tmp_path / "cache"))
    for _ in range(2):
        assert main(["show", str(bad)]) == 2
        assert "derive: error:" in capsys.readouterr().err
    assert not (tmp_path / "cache" / "show").exists()
    assert main(["show", str(arm)]) == 0
    first = capsys.readouterr().out
    (entry,) = (tmp_path / "cache" / "show").glob("*.json")
    entry.write_text("{not json")
    assert main(["show", str(arm)]) == 0 and capsys.readouterr().out == first
    assert json.loads(entry.read_text())["stdout"] == first


def test_version_is_printed_on_stdout_and_read_only_when_asked(tmp_path):
    """`derive --version` prints `derive <version>` on stdout, exit 0; any other command does not
    read the distribution's metadata (importlib.metadata: about 30 ms a command)."""
    import os

    from derive.version import __version__

    p = subprocess.run([sys.executable, "-m", "derive", "--version"], capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 0 and p.stdout.strip() in (f"derive {__version__}", "derive unknown (not installed)")
    code = "import sys; from derive.cli import _parser; _parser(['show']); " \
           "print('metadata' if 'importlib.metadata' in sys.modules else 'none')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                         env=dict(os.environ)).stdout.strip()
    assert out == "none"
