"""Templates (Jinja2, autoescaped: every name and value from the results is text, never markup)
and the page's own stylesheet and scripts, inlined so a page works copied on its own."""

from __future__ import annotations

import math
from functools import lru_cache
from importlib.resources import files
from pathlib import Path

from jinja2 import Environment, PackageLoader, StrictUndefined
from markupsafe import Markup

from ..results import replace_atomically
from .images import LEGEND
from .stored import SAFE_NAME


def number(value, digits: int = 3) -> str:
    """``0.0123`` -> ``0.0123``; None, NaN and text that is no number -> ``""``."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return ""
    if not math.isfinite(x):
        return ""
    return f"{x:.{digits}g}"


@lru_cache(maxsize=None)
def asset(name: str) -> Markup:
    """A file of static/ as trusted page content (the package's own CSS and JavaScript)."""
    return Markup((files("harness.report") / "static" / name).read_text(encoding="utf-8"))


@lru_cache(maxsize=1)
def environment() -> Environment:
    env = Environment(loader=PackageLoader("harness.report", "templates"), autoescape=True,
                      undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters["num"] = number
    env.globals["asset"] = asset
    env.globals["image_legend"] = LEGEND
    env.tests["safe_name"] = lambda text: bool(SAFE_NAME.fullmatch(str(text)))
    return env


def render(template: str, **context) -> str:
    return environment().get_template(template).render(**context)


def write_page(path: Path, text: str) -> Path:
    """Replace ``path`` whole (:func:`harness.results.replace_atomically`)."""
    replace_atomically(path, lambda f: f.write(text.encode("utf-8")))
    return path
