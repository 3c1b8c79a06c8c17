"""The documentation site (issue 36): its generated reference covers every command option and every
arm-file key, its code examples fit derive, and its checks catch what they are for. Fast: nothing is
built or run here (`make docs` builds the site and runs the marked examples)."""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))

from gen import bench, capi, cli, examples, keys  # noqa: E402

from derive.cli import COMMANDS, _parser, command_parsers  # noqa: E402
from derive.model import keydocs  # noqa: E402
from derive.model.simspec import SimSettings  # noqa: E402


@pytest.fixture(scope="module")
def commands_page() -> str:
    return cli.page()


def test_command_parsers_are_the_ones_derive_uses():
    """command_parsers builds each command's parser as `derive COMMAND` does: the same options."""
    _, parsers = command_parsers()
    assert list(parsers) == list(COMMANDS)
    for name, parser in parsers.items():
        alone = _parser([name])
        sub = next(a for a in alone._actions if isinstance(a, argparse._SubParsersAction)).choices[name]
        assert [a.option_strings or a.dest for a in sub._actions] == \
            [a.option_strings or a.dest for a in parser._actions], name


def test_commands_reference_lists_every_command_and_option(commands_page):
    _, parsers = command_parsers()
    for name, parser in parsers.items():
        section = commands_page.split(f"## derive {name}\n", 1)[1].split("\n## derive ", 1)[0]
        for action in cli.options(parser):
            shown = action.option_strings or [action.metavar or action.dest]
            for flag in shown:
                assert f"`{flag}`" in section, f"derive {name}: {flag} missing from the command reference"


def test_arm_file_reference_lists_every_key():
    assert keydocs.coverage() == []
    page = keys.page()
    for table in keydocs.TABLES:
        section = page.split(f"## `{table.header}`", 1)[1].split("\n## ", 1)[0]
        for key in table.reader_keys():
            assert f"| `{key}` |" in section, f"{table.header} {key} missing from the arm-file reference"


def test_keydocs_coverage_names_an_undocumented_key(monkeypatch):
    from derive.model import payload

    monkeypatch.setattr(payload, "KEYS", {**payload.KEYS, "spin": None})
    assert keydocs.coverage() == ["[payload]: key 'spin' is read (derive.model.payload:KEYS) but not documented"]
    with pytest.raises(ValueError, match="spin"):
        keys.page()


def test_simulation_defaults_are_the_readers():
    """The documented default of every scalar [simulation] key is SimSettings' own."""
    documented = {k.name: k.default for t in keydocs.TABLES if t.header == "[simulation]" for k in t.keys}
    defaults = SimSettings()
    for name in ("duration", "sample_time", "substeps", "pulse_period", "amplitude_deg", "payload_scale",
                 "payload_mass", "tacho_filter_hz", "seed"):
        assert float(documented[name]) == getattr(defaults, name), name
    assert documented["mujoco_contacts"] == str(defaults.mujoco_contacts).lower()
    assert documented["reference_start"] == f'"{defaults.reference_start}"'


def test_every_example_fits_derive():
    count, problems = examples.check_all()
    assert problems == []
    assert count >= 20
    assert examples.runnable(), "the getting-started example is run by make docs"


@pytest.mark.parametrize("lang, code, expected", [
    ("sh", "derive generate --no-such-option 1", "unrecognized arguments: --no-such-option"),
    ("sh", ".venv/bin/derive simulate --plant gazebo", "invalid choice: 'gazebo'"),
    ("sh", "derive frobnicate", "invalid choice: 'frobnicate'"),
    ("sh", "make docs bogus-target", "no make target 'bogus-target'"),
    ("sh", "python -m benchmarks nosuch", "no benchmark section 'nosuch'"),
    ("sh", ".venv/bin/python -m benchmarks.nosuch", "no module 'benchmarks.nosuch'"),
    ("sh", "pip install 'derive[nosuch]'", "no extra 'nosuch'"),
    ("python", "import derive\nderive.no_such_function()", "derive.no_such_function does not exist"),
    ("python", "def broken(:", "not Python"),
    ("toml", "[controller]\nT3 = 1", "[controller] has no key 'T3'"),
    ("toml", "[simulation]\nsubsteps = 4\n[sweep.vary]\nmass = 1", "[sweep.vary] has no key 'mass'"),
    ("toml", "[gripper]\nforce = 1", "no top-level table 'gripper'"),
    ("c", "glasgow_2link_pid_step(&s);", "glasgow_2link_pid_step is declared in no generated header"),
])
def test_example_checks_catch_a_renamed_name(lang, code, expected):
    block = examples.Block("page.md", 3, lang, code)
    problems = examples.check_block(block)
    assert problems and all(p.startswith("docs/page.md:3: ") for p in problems)
    assert any(expected in p for p in problems), problems


def test_example_checks_accept_what_derive_accepts():
    ok = ["derive --version", "derive generate my_arm.toml --out out --real float --params runtime  # comment",
          "derive sweep my_arm.toml --dask tcp://scheduler:8786 \\\n  --out sweep/my_arm && make test"]
    for code in ok:
        assert examples.check_block(examples.Block("p.md", 1, "sh", code)) == [], code


def test_c_api_reference_lists_every_function():
    page = capi.page()
    for name in capi.HEADERS:
        text = (ROOT / "generated" / capi.ARM / "c" / name).read_text(encoding="utf-8")
        for function in re.findall(r"\b(glasgow_2link_\w+)\(", text):
            assert f"{function}(" in page, function


def test_benchmark_placeholders_name_tables():
    tables = bench.tables()
    used = {m for page in examples.pages() for m in bench.PLACEHOLDER.findall(page.read_text(encoding="utf-8"))}
    assert used <= set(tables)
    assert used == set(tables), f"tables no page shows: {sorted(set(tables) - used)}"
    for table in tables.values():
        bench.render(table)   # every row as long as the header
    with pytest.raises(KeyError):
        bench.substitute("<!-- bench: no_such_table -->")


def test_blocks_read_fences_and_run_markers(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("text\n\n<!-- docs: run -->\n<!-- docs: files a/b.urdf c/d.toml:my_arm.toml -->\n```sh\n"
                    "derive show\n```\n\n    ```toml\n    [arm]\n    name = \"x\"\n    ```\n", encoding="utf-8")
    first, second = examples.blocks(page)
    assert (first.lang, first.code, first.run, first.files, first.line) == \
        ("sh", "derive show", True, ("a/b.urdf", "c/d.toml:my_arm.toml"), 5)
    assert (second.lang, second.code, second.run) == ("toml", '[arm]\nname = "x"', False)
    assert examples.check_block(second) == []


def test_metrics_table_is_the_committed_run():
    assert [bench.short(x) for x in (0.0008850494, 0.03, 0.052, 1.3e-12, 12.5)] == \
        ["8.9e-4", "3.0e-2", "5.2e-2", "1.3e-12", "1.2e1"]
    table = bench.metrics_table()
    for _, label in bench.FORMS:
        assert f"| {label} | 1 / 2 | " in table
    assert bench.substitute("<!-- metrics: default experiment -->") == table


def test_readme_is_a_landing_page_whose_links_exist():
    """The README is the landing page (issue 36): under 250 lines, the two set-up commands, and every
    relative link and image it names exists."""
    import re

    root = Path(__file__).resolve().parent.parent
    text = (root / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) < 250
    assert "make generate" in text and "make test" in text
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    assert targets, "no links"
    missing = [t for t in targets if not t.startswith("http") and not (root / t).exists()]
    assert missing == []
