"""Every JSON derive writes is strict RFC 8259 (issue 10, item 6).

``derive simulate --duration 2 --controllers npid --json m.json`` wrote
``"steady_state_error": NaN``: no sample of a 2 s run is settled, and Python's json
writes NaN as a bare word that strict parsers refuse. Now an undefined figure is
``null`` with ``<key>_undefined`` (the reason) beside it, every writer goes through
:mod:`derive.jsonio` (``allow_nan=False``; checked on the source of every module), and
what derive writes is read back here with a parser that refuses NaN and Infinity.
"""
from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import pytest

from derive import jsonio
from derive.cli import main

ROOT = Path(__file__).resolve().parent.parent


def test_strict_loads_refuses_nan_infinity_and_duplicate_keys():
    for text in ('{"x": NaN}', '[Infinity]', '{"x": -Infinity}'):
        with pytest.raises(ValueError, match="not RFC 8259 JSON"):
            jsonio.loads(text)
        json.loads(text)  # what Python's own parser lets through
    with pytest.raises(ValueError, match="the key 'a' appears twice"):
        jsonio.loads('{"a": 1, "a": 2}')
    assert jsonio.loads('{"a": [1, 2.5, null, "x"]}') == {"a": [1, 2.5, None, "x"]}


def test_dumps_names_a_non_finite_figure_instead_of_writing_nan():
    with pytest.raises(ValueError, match=r"controllers\.npid\.links\[1\]\.rms_error: nan is not a JSON number"):
        jsonio.dumps({"controllers": {"npid": {"links": [{"rms_error": 1.0}, {"rms_error": math.nan}]}}})
    with pytest.raises(ValueError, match=r"x\[0\]: inf is not a JSON number"):
        jsonio.dumps({"x": [math.inf]})
    with pytest.raises(ValueError, match=r"x\[0\]: an undefined figure needs a key"):
        jsonio.dumps({"x": [jsonio.Undefined("why")]})
    with pytest.raises(TypeError, match=r"x: complex is not JSON data"):
        jsonio.dumps({"x": 1j})


def test_an_undefined_figure_is_null_with_its_reason_beside_it():
    text = jsonio.dumps({"steady_state_error": jsonio.Undefined("no settled sample"), "rms_error": 0.5})
    assert jsonio.loads(text) == {"rms_error": 0.5, "steady_state_error": None,
                                  "steady_state_error_undefined": "no settled sample"}


def test_figures_at_a_stated_precision_do_not_carry_the_last_bits():
    assert jsonio.dumps({"x": 0.1 + 0.2}, digits=7, indent=None) == '{"x": 0.3}\n'
    assert jsonio.dumps({"x": 0.30000000000000004}, indent=None) == '{"x": 0.30000000000000004}\n'
    a, b = 0.0032406113603927846, 0.0032406113603927846 * (1 + 3e-14)  # another CPU's libm
    assert a != b and jsonio.dumps([a], digits=7) == jsonio.dumps([b], digits=7) == "[\n  0.003240611\n]\n"
    assert jsonio.dumps({"n": 3, "ok": True, "t": (1, 2)}, indent=None) == '{"n": 3, "ok": true, "t": [1, 2]}\n'


def test_no_module_writes_json_but_through_jsonio():
    """The kind: a new writer cannot bypass the strict one. In derive/, json.dump/json.dumps
    are called only in jsonio (under any name the json module is imported as); no module
    imports dump, dumps or JSONEncoder from json, nor another JSON library."""
    found = []
    for path in sorted((ROOT / "derive").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        where = f"{path.relative_to(ROOT).as_posix()}"
        aliases = {"json"}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name == "json":
                        aliases.add(alias.asname or "json")
                    elif alias.name.split(".")[0] in ("simplejson", "ujson", "orjson", "rapidjson"):
                        found.append(f"{where}:{node.lineno} imports {alias.name}")
            elif isinstance(node, ast.ImportFrom) and node.module:
                if node.module == "json" and {a.name for a in node.names} & {"dump", "dumps", "JSONEncoder", "*"}:
                    found.append(f"{where}:{node.lineno} from json import")
                elif node.module.split(".")[0] in ("simplejson", "ujson", "orjson", "rapidjson"):
                    found.append(f"{where}:{node.lineno} from {node.module} import")
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr in ("dump", "dumps") and isinstance(node.func.value, ast.Name)
                    and node.func.value.id in aliases):
                found.append(f"{where}:{node.lineno}")
    assert found == ["derive/jsonio.py:" + str(_line_of_dumps())], found


def _line_of_dumps() -> int:
    lines = (ROOT / "derive" / "jsonio.py").read_text(encoding="utf-8").splitlines()
    return next(i for i, line in enumerate(lines, 1) if "json.dumps(" in line)


def _strict(text: str):
    """Python's own parser, refusing what is not RFC 8259 (NaN, Infinity, -Infinity)."""
    def refuse(name: str):
        raise ValueError(f"not RFC 8259: {name}")

    return json.loads(text, parse_constant=refuse)


def test_committed_json_files_are_strict():
    """Every JSON file in generated/ (generate's manifest, simulate's metrics and manifests,
    sweep's report and manifest) parses with a parser that refuses NaN and Infinity."""
    files = sorted(p.relative_to(ROOT / "generated").as_posix() for p in (ROOT / "generated").rglob("*.json"))
    writers = {"glasgow_2link/MANIFEST.json", "glasgow_2link/sim/metrics.json", "glasgow_2link/sim/MANIFEST.json",
               "glasgow_2link/sweep/sweep.json", "glasgow_2link/sweep/MANIFEST.json"}
    assert writers <= set(files), files
    for name in files:
        text = (ROOT / "generated" / name).read_text(encoding="utf-8")
        _strict(text)
        jsonio.loads(text)  # and no key twice
    with pytest.raises(ValueError, match="not RFC 8259: NaN"):
        _strict('{"steady_state_error": NaN}')


def test_simulate_json_of_a_2s_run_has_null_with_reasons_not_nan(tmp_path, capsys):
    """The instance: in 2 s no link reaches a settled part of the pulse train (link 1 from
    t = 12 s, the last 20% of the first 15 s half-period; link 2, starting at 5 s, from 4 s)."""
    js, out = tmp_path / "m.json", tmp_path / "sim"
    assert main(["simulate", "--duration", "2", "--controllers", "npid", "--json", str(js), "--out", str(out)]) == 0
    capsys.readouterr()
    text = js.read_text(encoding="utf-8")
    assert "NaN" not in text and "Infinity" not in text
    doc = jsonio.loads(text)
    links = doc["controllers"]["npid"]["links"]
    assert [link["steady_state_error"] for link in links] == [None, None]
    assert links[0]["steady_state_error_undefined"] == (
        "no settled sample: the run ends at t = 1.998 s, before link 1's first settled part (the last 20% of "
        "a half-period of the pulse train) begins at t = 12 s")
    assert "begins at t = 4 s" in links[1]["steady_state_error_undefined"]
    assert all(link["rms_error"] > 0 and link["control_effort"] > 0 for link in links)
    assert doc["_precision"] == "7 significant digits"
    jsonio.loads((out / "MANIFEST.json").read_text(encoding="utf-8"))
    md = (out / "metrics.md").read_text(encoding="utf-8")
    assert "| npid | 1 |" in md and "| undefined |" in md and "npid, link 2, steady_state_error: no settled" in md
