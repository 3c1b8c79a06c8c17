"""`python -m benchmarks --json PATH` (issue 36): the run recorded as strict JSON, merged section by
section, never half-written, and rendered by the docs exactly as it was printed; the committed
snapshot docs/data/bench-run.json covers every section and every page's placeholder. Fast: the
sections run here are fakes, nothing is measured."""
from __future__ import annotations

import re
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))

from gen import bench, examples  # noqa: E402

import benchmarks.__main__ as bench_main  # noqa: E402
from benchmarks import Goal, Section  # noqa: E402
from derive.jsonio import dumps, loads  # noqa: E402

FAKE_A = Section("Fake A: a table, a note, two goals",
                 ("| arm | time |\n| --- | --: |\n| panda | 1.5 ms |", "A note with `code` and 7 %."),
                 (Goal("under 2 ms", True, "1.5 ms"), Goal("under 1 ms", False, "1.5 ms")))
FAKE_B = Section("Fake B", ("| x |\n| --: |\n| 1 |",))


def _fake(name: str, run) -> types.ModuleType:
    module = types.ModuleType(f"benchmarks.{name}")
    module.TITLE = name
    module.run = run
    return module


@pytest.fixture
def fakes(monkeypatch):
    """Sections fake_a, fake_b (returning FAKE_A, FAKE_B) and fake_fail (raising), listed in SECTIONS."""
    def fail():
        raise RuntimeError("a wrong result")

    for name, run in (("fake_a", lambda: FAKE_A), ("fake_b", lambda: FAKE_B), ("fake_fail", fail)):
        monkeypatch.setitem(sys.modules, f"benchmarks.{name}", _fake(name, run))
    monkeypatch.setattr(bench_main, "SECTIONS", bench_main.SECTIONS + ("fake_a", "fake_b", "fake_fail"))


def test_json_records_the_section_as_printed(fakes, tmp_path, capsys):
    path = tmp_path / "run.json"
    assert bench_main.main(("fake_a",), path) == 0
    printed = capsys.readouterr().out
    text = path.read_text(encoding="utf-8")
    assert text.endswith("}\n") and "NaN" not in text and "Infinity" not in text
    data = loads(text)   # strict: no NaN, no duplicate keys
    assert text == dumps(data)   # sorted keys, indented, trailing newline
    [record] = data["sections"]
    assert record["module"] == "fake_a" and record["title"] == FAKE_A.title
    assert record["blocks"] == list(FAKE_A.blocks)
    assert record["goals"] == [{"text": g.text, "met": g.met, "measured": g.measured} for g in FAKE_A.goals]
    assert record["command"] == f"python -m benchmarks --json {path} fake_a"
    assert record["date"].endswith("+00:00") and record["seconds"] >= 0
    for key in ("python", "sympy", "numpy", "casadi", "machine", "cpus"):
        assert key in record, key
    assert FAKE_A.markdown() in printed
    rendered = bench.render_run(record)
    assert FAKE_A.markdown() == f"## {FAKE_A.title}\n\n" + rendered[:rendered.index("\n*Measured by")]
    assert "PASS: under 2 ms (1.5 ms)" in rendered and "MISS: under 1 ms (1.5 ms)" in rendered
    assert rendered.endswith(f"*Measured by `make bench` (`python -m benchmarks fake_a`) on {record['date'][:10]}, "
                             f"{record['machine']} ({record['cpus']} CPUs), Python {record['python']}, "
                             f"SymPy {record['sympy']}.*")


def test_json_layout_is_deterministic(fakes, tmp_path, monkeypatch):
    """The same records give the same bytes: sorted keys, sections in SECTIONS' order, a final newline."""
    monkeypatch.setattr(bench_main, "_now", lambda: "2026-12-07T00:00:00+00:00")
    monkeypatch.setattr(bench_main.time, "perf_counter", lambda: 0.0)
    one, two = tmp_path / "one.json", tmp_path / "two.json"
    bench_main.main(("fake_a", "fake_b"), one, command="c")
    bench_main.main(("fake_b", "fake_a"), two, command="c")
    assert one.read_bytes() == two.read_bytes()
    assert [s["module"] for s in loads(one.read_text())["sections"]] == ["fake_a", "fake_b"]


def test_a_run_of_one_section_merges_into_the_snapshot(fakes, tmp_path):
    path = tmp_path / "run.json"
    bench_main.main(("fake_b",), path)
    first = loads(path.read_text())["sections"][0]
    bench_main.main(("fake_a",), path, command="the second run")
    sections = loads(path.read_text())["sections"]
    assert [s["module"] for s in sections] == ["fake_a", "fake_b"]   # SECTIONS' order, not run order
    assert sections[1] == first   # kept with its own command, date and versions
    assert sections[0]["command"] == "the second run"
    bench_main.main(("fake_a",), path, command="a third run")
    assert [s["command"] for s in loads(path.read_text())["sections"]] == ["a third run", first["command"]]


def test_a_failing_section_writes_nothing(fakes, tmp_path):
    path = tmp_path / "run.json"
    with pytest.raises(RuntimeError, match="a wrong result"):
        bench_main.main(("fake_a", "fake_fail"), path)
    assert not path.exists() and list(tmp_path.iterdir()) == []
    bench_main.main(("fake_b",), path)
    before = path.read_bytes()
    with pytest.raises(RuntimeError):
        bench_main.main(("fake_a", "fake_fail"), path)
    assert path.read_bytes() == before and list(tmp_path.iterdir()) == [path]


def test_a_broken_snapshot_fails_before_any_section_runs(fakes, tmp_path, capsys):
    path = tmp_path / "run.json"
    path.write_text('{"sections": [], "x": NaN}\n', encoding="utf-8")
    with pytest.raises(ValueError, match="NaN"):
        bench_main.main(("fake_a",), path)
    assert "## Fake A" not in capsys.readouterr().out


def test_cli_refuses_an_unknown_section(capsys):
    assert bench_main.cli(["--json", "x.json", "nosuch"]) == 2
    assert "unknown section(s) nosuch" in capsys.readouterr().err
    assert bench_main.cli(["--json"]) == 2


def test_docs_render_a_missing_section_as_an_error_naming_it():
    with pytest.raises(bench.MissingRun, match="'nosuch'"):
        bench.section({"dynamics": {}}, "nosuch")
    with pytest.raises(bench.MissingRun, match="no section 'nosuch' in docs/data/bench-run.json"):
        bench.substitute("# A page\n\n<!-- bench-run: nosuch -->\n")



def test_a_pipe_in_a_cell_is_escaped_so_the_table_keeps_its_columns():
    from benchmarks import table

    text = table(("arm", "||W||_2"), [("chain2", "0.5474")])
    assert text.splitlines()[0] == "| arm    | \\|\\|W\\|\\|_2 |"
    assert {len(_cells(line)) for line in text.splitlines()} == {2}


def _cells(line: str) -> list[str]:
    """The cells of a Markdown table row (an escaped ``\\|`` stays in its cell)."""
    return re.split(r"(?<!\\)\|", line.strip())[1:-1]


# sections of benchmarks/__main__.py's SECTIONS left out of the committed snapshot (none: every one ran)
EXCLUDED: tuple[str, ...] = ()


def test_committed_snapshot_covers_sections_and_placeholders():
    text = bench.RUN.read_text(encoding="utf-8")
    sections = bench.runs()   # strict JSON (derive.jsonio.loads)
    assert text == dumps(loads(text))   # the layout python -m benchmarks --json writes
    assert list(sections) == [s for s in bench_main.SECTIONS if s not in EXCLUDED]
    for name, record in sections.items():
        assert record["blocks"] and record["seconds"] > 0, name
        assert record["command"].startswith("python -m benchmarks --json docs/data/bench-run.json"), name
        for part in (p for block in record["blocks"] for p in block.split("\n\n")):
            lines = part.splitlines()
            if lines and all(line.startswith("|") for line in lines):   # a table keeps its columns on every row
                assert len({len(_cells(line)) for line in lines}) == 1, (name, part[:200])
        bench.render_run(record)
    used = {m for page in examples.pages() for m in bench.RUN_PLACEHOLDER.findall(page.read_text(encoding="utf-8"))}
    assert used == set(sections), f"sections no page shows or pages naming no section: {sorted(used ^ set(sections))}"


def test_rendered_text_keeps_tag_like_words():
    """A printed '<string>' (a traceback in a corpus cell) is shown, not swallowed as an HTML tag; code spans
    and comparisons stay as printed."""
    tag_safe = bench.tag_safe
    assert tag_safe('File "<string>", line 22') == 'File "&lt;string>", line 22'
    assert tag_safe("`a <b>` and x < 1 and </i>") == "`a <b>` and x < 1 and &lt;/i>"
