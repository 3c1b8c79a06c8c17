"""Arm files for the MuJoCo-plant tests: copies of the vendored URDF arms (tests/data/urdf) in a
temporary folder, with the test's [simulation] settings, observer gains that the sample time
allows (derive.control.sampling), and optionally the URDF's <dynamics friction> set.

Without that option the copy's [simulation] states coulomb_friction = [0.05, 0.01, ...] (the
simspec default, derive.model.simspec) unless the test gives its own: the UR5's, Panda's and
Kinova's URDFs write <dynamics friction="0.0">, which is a URDF arm's coulomb_friction default
(derive.model.spec), and these tests compare the plants with the smooth Coulomb friction on
(MuJoCo's through derive's passive callback), the stiff wrists they describe included."""
from __future__ import annotations

import re
import shutil
from pathlib import Path

from derive.model.simspec import default_settings

DATA = Path(__file__).resolve().parent / "data" / "urdf"

# arm -> (observer gain w of every joint [N m s/rad], sample time [s], RK4 steps per sample): the DOBC and
# NPID sample-time limits (derive check) are then 5.3 ms (UR5), 1.23 ms (Panda), 2.15 ms (Kinova,
# w = 0.05: its light wrist), 2.79 ms (double pendulum, w = 0.5); the Kinova's wrist with the
# default smooth Coulomb friction decays at 11,400 1/s, beyond RK4 at h = 0.5 ms (h lambda = 5.7 >
# 2.785, derive.sim.plant.stiffest_mode): 16 steps per sample (h lambda = 1.4); the synthetic arm
# (4 joints, the last prismatic): 6.0 ms
SETTINGS = {"ur5": (5.0, 0.002, 4), "panda": (5.0, 0.001, 4), "kinova": (0.05, 0.002, 16),
            "double_pendulum": (0.5, 0.002, 4), "synthetic": (5.0, 0.002, 4)}


def toml_value(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(v)


def arm_copy(folder: Path, name: str, simulation: dict | None = None, friction: float | None = None,
             extra: str = "") -> Path:
    """``name``'s arm file and URDF copied into ``folder``; ``simulation``: keys of its
    [simulation] (sample_time and substeps default to SETTINGS); ``friction``: every moving joint's
    <dynamics friction> [N m or N] in the copy (its damping kept); ``extra``: text appended to the arm file."""
    w, dt, substeps = SETTINGS[name]
    text = (DATA / f"{name}.toml").read_text()
    # the starter file's own W (a full matrix, derive init) and its [simulation] give way to the
    # test's diagonal w and settings above; its speed box too, so the limits are those stated above
    n = text.count("\n[[motor]]")
    text = re.sub(r"^w = \[(?:[^\[\]]|\[[^\]]*\])*\]", "w = [" + ", ".join([repr(w)] * n) + "]", text, flags=re.M)
    text = re.sub(r"^max_joint_speed = .*\n", "", text, flags=re.M)
    text = re.sub(r"^\[simulation\]\n(?:(?!\[).*\n?)*", "", text, flags=re.M)
    table = {"sample_time": dt, "substeps": substeps, **(simulation or {})}
    if friction is None and "coulomb_friction" not in table:
        table["coulomb_friction"] = list(default_settings(n).coulomb_friction)
    text += "\n[simulation]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in table.items()) + extra
    urdf = (DATA / f"{name}.urdf").read_text()
    if friction is not None:
        urdf = re.sub(r'(<dynamics[^>]*?)\s*friction="[^"]*"', r"\1", urdf)
        def rough(joint: re.Match) -> str:
            text = re.sub(r'(<dynamics[^>]*?)\s*friction="[^"]*"', r"\1", joint.group(0))
            if "<dynamics" in text:
                return text.replace("<dynamics", f'<dynamics friction="{friction!r}"')
            return text.replace("</joint>", f'<dynamics friction="{friction!r}"/></joint>')
        urdf = re.sub(r'<joint name="[^"]*" type="(?:revolute|continuous|prismatic)">.*?</joint>', rough, urdf,
                      flags=re.S)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.urdf").write_text(urdf)
    path = folder / f"{name}.toml"
    path.write_text(text)
    return path


def copy_file(src: Path, folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    return Path(shutil.copy(src, folder / src.name))
