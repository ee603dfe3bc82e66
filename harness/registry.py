"""Technique discovery through the ``shadowbench.techniques`` entry-point group.

Built-in techniques register exactly as a third-party package would: an entry point
``name = "package.module:Class"`` in that group. Two entry points with one name are an error, and
so is a bad quality-knob or declined-light declaration: each is bad input (exit 2), naming the
technique and key.
"""

from __future__ import annotations

from functools import lru_cache
from importlib.metadata import entry_points

from .code_version import GROUP
from .config import ConfigError
from .technique import Technique, check_declined_lights, check_quality_knobs


class RegistryError(ConfigError):
    """A technique that cannot be registered as declared."""


@lru_cache(maxsize=1)
def techniques() -> dict[str, type[Technique]]:
    found: dict[str, type[Technique]] = {}
    origin: dict[str, str] = {}
    for ep in entry_points(group=GROUP):
        if ep.name in found:
            raise RegistryError(
                f"technique {ep.name!r} is registered twice: {origin[ep.name]} and {ep.value}"
            )
        cls = ep.load()
        if not (isinstance(cls, type) and issubclass(cls, Technique)):
            raise RegistryError(f"entry point {ep.name} = {ep.value} is not a Technique subclass")
        if cls.name != ep.name:
            raise RegistryError(
                f"entry point {ep.name!r} loads {ep.value}, whose name is {cls.name!r}"
            )
        try:
            check_quality_knobs(cls)
        except ValueError as e:
            raise RegistryError(f"technique {ep.name!r} ({ep.value}): quality_knobs.{e}") from None
        try:
            check_declined_lights(cls)
        except ValueError as e:
            raise RegistryError(f"technique {ep.name!r} ({ep.value}): declines_lights.{e}") \
                from None
        found[ep.name], origin[ep.name] = cls, ep.value
    return dict(sorted(found.items()))


def baseline() -> str | None:
    """The name of the registered technique that declares itself the baseline (None when
    none does)."""
    marked = [name for name, cls in techniques().items() if cls.baseline]
    if len(marked) > 1:
        raise RegistryError(f"techniques {', '.join(marked)} each declare baseline = True; "
                            "one baseline at most")
    return marked[0] if marked else None


def get(name: str) -> type[Technique]:
    registered = techniques()
    if name not in registered:
        raise KeyError(f"unknown technique {name!r}; registered: {', '.join(registered)}")
    return registered[name]
