"""Where derive's own files are: the package, the Jinja2 templates and the packaged arm files."""
from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
# an installed wheel: derive/templates (setup.py copies them there); a source tree or an
# editable install: the repository's top-level templates/
TEMPLATES = PACKAGE / "templates" if (PACKAGE / "templates").is_dir() else PACKAGE.parent / "templates"
DEFAULT_ARM = "glasgow_2link"
ARMS_DIR = PACKAGE / "model" / "arms"


def packaged_arms() -> tuple[str, ...]:
    """Names of the arm files shipped in ``derive/model/arms``."""
    return tuple(sorted(p.stem for p in ARMS_DIR.glob("*.toml")))


def resolve_arm_path(arm: str | Path | None) -> Path:
    """A path, or the name of a packaged arm, or None (the default arm).

    A name without a suffix is, in this order, the name of a packaged arm, a file
    of that name, or that name with ``.toml`` appended (``derive show my3`` reads
    ``./my3.toml``)."""
    if arm is None:
        return ARMS_DIR / f"{DEFAULT_ARM}.toml"
    path = Path(arm)
    if path.suffix != ".toml" and str(arm) in packaged_arms():
        return ARMS_DIR / f"{arm}.toml"
    if path.suffix == "" and not path.exists() and Path(f"{arm}.toml").is_file():
        return Path(f"{arm}.toml")
    return path
