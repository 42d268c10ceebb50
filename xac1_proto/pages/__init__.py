"""HTML and Markdown pages from Jinja2 templates: one environment, autoescaped, shared by every report.

The conformance report and the session report render through ``render(name, **context)``; templates
live in ``templates/`` beside this file (``*.html.j2`` autoescaped, ``*.md.j2`` not). Pages are
self-contained: styles and scripts go inline, nothing is fetched when a page is opened.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import jinja2


@cache
def environment() -> jinja2.Environment:
    """The one Jinja2 environment (loaded on first use, so importing this module costs nothing)."""
    return jinja2.Environment(
        loader=jinja2.PackageLoader("xac1_proto.pages", "templates"),
        autoescape=jinja2.select_autoescape(enabled_extensions=("html.j2", "html"),
                                            default_for_string=True),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


def render(name: str, **context: Any) -> str:
    """Render the template ``name`` (e.g. ``conformance.html.j2``) with ``context``."""
    return environment().get_template(name).render(**context)
