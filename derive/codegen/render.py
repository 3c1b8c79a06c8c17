"""One strict Jinja2 environment; templates render views to strings."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import jinja2

_PACKAGE = Path(__file__).resolve().parents[1]
# an installed wheel: derive/templates (setup.py copies them there); a source tree or an
# editable install: the repository's top-level templates/
TEMPLATES = _PACKAGE / "templates" if (_PACKAGE / "templates").is_dir() else _PACKAGE.parent / "templates"


@lru_cache(maxsize=None)
def environment(root: str = str(TEMPLATES)) -> jinja2.Environment:
    """StrictUndefined (a missing view field is an error), trimmed blocks,
    trailing newlines kept, no autoescaping (the output is code, not HTML)."""
    return jinja2.Environment(loader=jinja2.FileSystemLoader(root), undefined=jinja2.StrictUndefined,
                              trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                              autoescape=False)


def render(template: str, **views: object) -> str:
    """Render ``template`` (a path under templates/) with the given views."""
    return environment().get_template(template).render(**views)
