"""One strict Jinja2 environment; templates render views to strings."""
from __future__ import annotations

from functools import lru_cache

import jinja2

from derive.paths import TEMPLATES


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
