"""Technique discovery through the ``shadowbench.techniques`` entry-point group.

Built-in techniques register exactly as a third-party package would: an entry point
``name = "package.module:Class"`` in that group. One entry point cannot break the others: one
that fails to import, loads no Technique, has another name than its class, is registered twice,
or declares bad quality knobs, declined lights, colour or tunable settings is *broken*
(:func:`broken`: its name with the reason), left out of :func:`techniques`, listed as broken by
``shadowbench list``, and bad input (exit 2, naming it) only where a command asks for it by name.

The baseline (the technique whose cost the dashboard divides the others' by) is declared in a
class's own body (``baseline = True``), never inherited: a plugin subclassing sm is not a second
baseline. Two declared baselines are a RegistryError naming both distributions and the fix at
``list`` and ``run``; ``report`` and ``compare`` ask only among the techniques of their folder.
"""

from __future__ import annotations

from functools import lru_cache
from importlib.metadata import entry_points

from .code_version import GROUP
from ..config import ConfigError
from . import Technique, check_declined_lights, check_quality_knobs, declares_baseline
from .colour import check_colour, declared_colour, name_colour
from .tunable import check_tunable

# the project's distribution (pyproject.toml's name; `shadowbench` on the package index is
# another project's): the built-ins'. Any other distribution is a plugin.
DISTRIBUTION = "hard-shadow-bench"


class RegistryError(ConfigError):
    """A technique that cannot be registered as declared."""


def distribution(ep) -> str:
    """The name of the installed distribution (package) that declares entry point ``ep``."""
    dist = getattr(ep, "dist", None)
    name = dist.metadata["Name"] if dist is not None else None
    return name or "an unknown distribution"


def _load(ep) -> type[Technique]:
    """The class of entry point ``ep``, checked; a RegistryError saying what is wrong."""
    try:
        cls = ep.load()
    except Exception as e:  # any error of a plugin's import is the plugin's, not ours
        reason = " ".join(f"{type(e).__name__}: {e}".split())
        raise RegistryError(f"cannot import {ep.value}: {reason}") from None
    if not (isinstance(cls, type) and issubclass(cls, Technique)):
        raise RegistryError(f"entry point {ep.name} = {ep.value} is not a Technique subclass")
    if cls.name != ep.name:
        raise RegistryError(f"entry point {ep.name!r} loads {ep.value}, whose name is {cls.name!r}")
    for check, key in ((check_quality_knobs, "quality_knobs."),
                       (check_declined_lights, "declines_lights."), (check_colour, "colour: "),
                       (check_tunable, "tunable.")):
        try:
            check(cls)
        except ValueError as e:
            raise RegistryError(f"technique {ep.name!r} ({ep.value}): {key}{e}") from None
    return cls


@lru_cache(maxsize=1)
def _discover() -> tuple[dict[str, type[Technique]], dict[str, str], dict[str, str]]:
    """(techniques by name, broken entry points by name with the reason, distribution of each
    name)."""
    found: dict[str, type[Technique]] = {}
    broken: dict[str, str] = {}
    origin: dict[str, str] = {}
    dist: dict[str, str] = {}
    for ep in entry_points(group=GROUP):
        where = f"{ep.value} ({distribution(ep)})"
        if ep.name in origin:
            found.pop(ep.name, None)
            broken[ep.name] = (f"technique {ep.name!r} is registered twice: {origin[ep.name]} and "
                               f"{where}; uninstall one")
            continue
        origin[ep.name], dist[ep.name] = where, distribution(ep)
        try:
            found[ep.name] = _load(ep)
        except RegistryError as e:
            broken[ep.name] = f"{e} [{distribution(ep)}]"
    return dict(sorted(found.items())), dict(sorted(broken.items())), dist


def techniques() -> dict[str, type[Technique]]:
    """The registered techniques that load and are declared right, by name."""
    return dict(_discover()[0])


def _discover_again() -> None:
    _discover.cache_clear()
    own_distribution.cache_clear()


techniques.cache_clear = _discover_again  # the tests' way to discover again


def broken() -> dict[str, str]:
    """Entry points of the group that cannot be used, each with the reason (one line)."""
    return dict(_discover()[1])


def distribution_of(name: str) -> str:
    return _discover()[2].get(name, "an unknown distribution")


@lru_cache(maxsize=1)
def own_distribution() -> str:
    """The installed name of the distribution that holds the built-ins: the one whose entry
    points in the group load from this project's ``techniques`` package (an environment
    installed before the project took its name holds it as ``shadowbench``), else
    :data:`DISTRIBUTION` (a checkout on the path, not installed)."""
    for ep in entry_points(group=GROUP):
        if ep.value.split(".", 1)[0] == "techniques":
            return distribution(ep)
    return DISTRIBUTION


def is_plugin(name: str) -> bool:
    """Whether technique ``name`` comes from another distribution than the built-ins'."""
    return distribution_of(name) != own_distribution()


def baseline(among=None) -> str | None:
    """The technique that declares itself the baseline in its own class body (None when none
    does), among the names ``among`` (every registered technique when None). Two or more are
    a RegistryError naming their distributions and the fix."""
    marked = [name for name, cls in techniques().items()
              if declares_baseline(cls) and (among is None or name in among)]
    if len(marked) > 1:
        named = ", ".join(f"{name} (distribution {distribution_of(name)})" for name in marked)
        raise RegistryError(f"techniques {named} each declare baseline = True in their class; one "
                            f"baseline at most: remove the line from all but one, or uninstall "
                            f"one of the distributions")
    return marked[0] if marked else None


def rivals(names) -> dict[str, tuple[str, ...]]:
    """Each registered technique among ``names`` with the rivals its class declares (a name
    not registered here, a plugin's not installed, has none)."""
    registered = techniques()
    return {name: tuple(registered[name].rivals) for name in names if name in registered}


def colour(name: str) -> str:
    """The technique's colour in every dashboard: the one its class declares, else its name's
    (a technique not installed here, a plugin's, has its name's)."""
    cls = techniques().get(name)
    return (declared_colour(cls) if cls is not None else None) or name_colour(name)


def get(name: str) -> type[Technique]:
    registered = techniques()
    if name in registered:
        return registered[name]
    problem = broken().get(name)
    if problem:
        raise RegistryError(f"technique {name!r} is broken: {problem}")
    raise KeyError(f"unknown technique {name!r}; registered: {', '.join(registered)}")


def stale_installs() -> list[str]:
    """One warning per editable install (``pip install -e``) whose source's pyproject.toml
    declares other entry points in the group than the installed metadata holds: entry points
    are read when a distribution is installed, so one added to (or removed from) its
    pyproject.toml since is missing (or still there) until it is installed again."""
    import json
    import tomllib
    from importlib.metadata import distributions
    from pathlib import Path
    from urllib.parse import unquote, urlparse

    warnings = []
    for dist in distributions():
        try:
            direct = json.loads(dist.read_text("direct_url.json") or "{}")
        except ValueError:
            continue
        if not direct.get("dir_info", {}).get("editable"):
            continue
        source = Path(unquote(urlparse(direct.get("url", "")).path))
        try:
            project = tomllib.loads((source / "pyproject.toml").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        declared = set(project.get("project", {}).get("entry-points", {}).get(GROUP, {}))
        loaded = {ep.name for ep in dist.entry_points.select(group=GROUP)}
        if declared == loaded:
            continue
        name = dist.metadata["Name"]
        missing, extra = sorted(declared - loaded), sorted(loaded - declared)
        what = "; ".join(filter(None, (
            missing and f"declared but not installed: {', '.join(missing)}",
            extra and f"installed but no longer declared: {', '.join(extra)}")))
        warnings.append(f"{name} is installed in editable mode and {source / 'pyproject.toml'} "
                        f"has other techniques than its installed entry points ({what}): "
                        f"install it again: pip install -e {source}")
    return warnings
