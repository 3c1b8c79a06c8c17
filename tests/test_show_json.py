"""``derive show --json FILE`` (issue 38: show states the payload limits in text and JSON): the numbers show
prints, strict JSON, the same as derive.control.sampling's and derive.control.payload's."""
from __future__ import annotations

import math
from pathlib import Path

from derive import jsonio
from derive.cli import main

DATA = Path(__file__).parent / "data" / "urdf"
PAYLOAD = "\n[payload]\nmass = 0.5\ncom = [0.0, 0.0, 0.0]\ncom_radius = 0.05\n"


def test_show_json_states_the_limits_and_the_payload(tmp_path, capsys):
    (tmp_path / "double_pendulum.urdf").write_text((DATA / "double_pendulum.urdf").read_text())
    arm = tmp_path / "dp.toml"
    arm.write_text((DATA / "double_pendulum.toml").read_text() + PAYLOAD)
    out = tmp_path / "show.json"
    assert main(["show", str(arm), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    doc = jsonio.loads(out.read_text())            # strict: no NaN, no duplicate keys
    from derive.control.payload.text import stated
    from derive.control.pipeline import derive
    from derive.control.sampling import FORMS, OBSERVERS, limits
    from derive.model.spec import load_arm

    d = derive(load_arm(arm))
    assert doc["arm"] == d.arm.name and doc["n"] == d.n == 2 and doc["sample_time"] == d.arm.simulation.sample_time
    for o in OBSERVERS:
        got = doc["sample_time_limits"][o]
        assert set(got) == set(FORMS)
        for f, lim in limits(d, o).items():
            assert got[f]["limit_s"] == (lim.limit if math.isfinite(lim.limit) else None)
            assert got[f]["points"] == lim.points > 0
    pay = doc["payload"]
    assert pay["range"] == {"mass": 0.5, "com": [0.0, 0.0, 0.0], "com_radius": 0.05}
    for f, lim in stated(d).items():
        assert pay["forms"][f]["limit_kg"] == lim.limit and pay["forms"][f]["holds"] == (lim.limit >= 0.5)
    assert "Payload: largest payload at sample_time" in text       # the text states the same
    assert f"DOBC {stated(d)['dobc'].limit:.3g} kg" in text


def test_show_json_without_payload_is_null(tmp_path):
    out = tmp_path / "show.json"
    assert main(["show", "--json", str(out)]) == 0          # the packaged glasgow_2link
    doc = jsonio.loads(out.read_text())
    assert doc["payload"] is None and doc["inputs_beyond_limits"] == []
    assert doc["sample_time_limits"]["explicit"]["dobc"]["limit_s"] > 0
