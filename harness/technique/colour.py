"""A technique's colour: the same in every chart and table of every dashboard, whatever else
a results folder holds.

A technique declares it in its own class body (``colour = "#1f77b4"``); the built-ins do, so
they are told apart on every page. One that declares none (a plugin, or a subclass, which does
not inherit its parent's: a plugin subclassing sm is not drawn as sm) gets the colour of its
name: a hash of the name into :data:`NAME_PALETTE`, well-separated colours that read on white.
Either way the colour depends on the name alone, never on which techniques ran beside it (an
index into a palette over the folder's techniques gave sm four colours in four dashboards).
Two names can hash to one colour; a plugin that meets one declares its own.

The declaration line (``colour = "#rrggbb"`` alone on its line in a class body, indented by
four spaces) does not enter the technique's
code version (:mod:`harness.technique.code_version`): it changes no result.
"""

from __future__ import annotations

import hashlib
import re

COLOUR = re.compile(r"#[0-9a-fA-F]{6}")
# a class body's declaration, as code_version leaves it out of the hash
DECLARATION = re.compile(rb"^    colour(?: *: *[\w|\[\]., ]+)? *= *[\"']#[0-9a-fA-F]{6}[\"'] *\n", re.M)
# Sasha Trubetskoy's 20 distinct colours less the six too light to read on white and the two
# greys (white's opposite and a mid grey: gmnpr's and rt's)
NAME_PALETTE = ("#e6194b", "#3cb44b", "#4363d8", "#f58231", "#911eb4", "#42d4f4", "#f032e6",
                "#469990", "#9a6324", "#800000", "#808000", "#000075")


def name_colour(name: str) -> str:
    """The colour of a technique that declares none: its name's SHA-256 into NAME_PALETTE."""
    digest = hashlib.sha256(name.encode("utf-8")).digest()
    return NAME_PALETTE[int.from_bytes(digest[:8], "big") % len(NAME_PALETTE)]


def declared_colour(cls) -> str | None:
    """The colour in the class's own body (``colour = "#rrggbb"``), None where it declares
    none."""
    return cls.__dict__.get("colour")


def check_colour(cls) -> None:
    """A declared colour is ``#rrggbb``; ValueError otherwise (it lands in a style attribute)."""
    value = declared_colour(cls)
    if value is not None and not (isinstance(value, str) and COLOUR.fullmatch(value)):
        raise ValueError(f"{value!r} is not a colour written #rrggbb (e.g. '#1f77b4')")


def strip_declaration(source: bytes) -> bytes:
    """A module's text as its code version hashes it: without a colour declaration line."""
    return DECLARATION.sub(b"", source)
