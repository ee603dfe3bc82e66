"""The input files shipped with shadowbench: ``scenes.yaml`` and ``experiments/`` (with the
meshes and scene files the experiments name). In a checkout or an editable install they lie at
the repository's root; a wheel carries them as package data, ``harness/shipped/`` (setup.py
copies them there at build time), so an installed shadowbench runs them from any folder.

What a user types: ``--scene-file F`` or ``./scenes.yaml`` where there is one, else the shipped
scenes; an experiment as a path (read as given where it exists: ``my.yaml``), or a shipped one
by name (``default``, ``hard_cases``, ``papers/sv``: ``experiments/NAME.yaml``) or by its path
in the repository (``experiments/default.yaml``, as the docs write it) from any folder."""

from __future__ import annotations

from pathlib import Path

from .yaml_source import ConfigError

HARNESS = Path(__file__).resolve().parent.parent
# a wheel's copy first; a checkout's (or an editable install's) root is the harness's parent
PLACES = (HARNESS / "shipped", HARNESS.parent)


def root() -> Path | None:
    """The folder that holds the shipped ``scenes.yaml`` and ``experiments/``; None when this
    installation has none."""
    return next((place for place in PLACES if (place / "scenes.yaml").is_file()), None)


def scene_file() -> Path | None:
    """The shipped scenes; None when there are none."""
    folder = root()
    return folder / "scenes.yaml" if folder else None


def experiments() -> list[str]:
    """The shipped experiments' names (``default``, ``papers/sv``): every YAML under
    ``experiments/`` with a ``techniques:`` key (a scene file has none)."""
    folder = root()
    if folder is None:
        return []
    names = []
    for path in sorted((folder / "experiments").rglob("*.yaml")):
        text = path.read_text(encoding="utf-8", errors="replace")
        if any(line.startswith("techniques:") for line in text.splitlines()):
            names.append(path.relative_to(folder / "experiments").with_suffix("").as_posix())
    return names


def experiment_file(text: str) -> Path:
    """The experiment a command reads: ``text`` where that path exists (a FIFO or folder is
    the reader's to refuse), else the shipped experiment it names, by name (``default``,
    ``papers/sv``) or by its path in the repository (``experiments/default.yaml``); a
    ConfigError naming the argument and the shipped names otherwise."""
    given = Path(text)
    if given.exists() or given.is_symlink():
        return given
    folder = root()
    if folder is not None and not given.is_absolute() and ".." not in given.parts:
        for candidate in (folder / "experiments" / given.with_suffix(".yaml"),
                          folder / "experiments" / given, folder / given):
            if candidate.suffix == ".yaml" and candidate.is_file():
                return candidate
    shipped = experiments()
    raise ConfigError(f"experiment {text}: no such file, and no shipped experiment of that name"
                      + (f"; shipped: {', '.join(shipped)}" if shipped else ""))
