"""What the commands' options name, checked the same way by each command: comma-separated
names, the ``--out`` folder, the scene file."""

from __future__ import annotations

import os
from pathlib import Path

from ..config import ConfigError, shipped

DEFAULT_SCENE_FILE = "scenes.yaml"


def names(option: str, text: str | None) -> list[str] | None:
    """``a,b`` -> ["a", "b"]; None when the option is absent; an error when it names nothing."""
    if text is None:
        return None
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise ConfigError(f"{option} {text!r}: names nothing; give comma-separated names, or "
                          "leave the option out for all")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"{option} {text!r}: names {', '.join(repeated)} more than once")
    return names


def check_out(text: str) -> None:
    """``--out`` must be, or be creatable as, a folder of our own: a ConfigError naming
    ``--out`` otherwise, before anything is planned or written."""
    out = Path(text).resolve()
    if out.parts[1:2] in (("proc",), ("sys",)):
        raise ConfigError(f"--out {text}: is under /{out.parts[1]}, the kernel's files, not a "
                          "place for results")
    existing = next(p for p in (out, *out.parents) if os.path.lexists(p))
    if not existing.is_dir():
        what = "is a file" if existing == out else f"lies under {existing}, a file"
        raise ConfigError(f"--out {text}: {what}, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        reason = ("Read-only file system" if os.statvfs(existing).f_flag & os.ST_RDONLY
                  else "permission denied")
        raise ConfigError(f"--out {text}: cannot write in {existing}: {reason}")


def scene_file(text: str | None) -> Path | None:
    """The scene file a command reads: ``--scene-file`` as given (a missing one is bad input),
    else ./scenes.yaml, else the scenes shipped with the package (:mod:`harness.config.shipped`:
    a wheel's package data, or a checkout's root); None when there is none."""
    if text is not None:
        if not Path(text).exists():  # a FIFO, socket or folder is said by the reader
            raise ConfigError(f"--scene-file {text}: no such file")
        return Path(text)
    if Path(DEFAULT_SCENE_FILE).is_file():
        return Path(DEFAULT_SCENE_FILE)
    return shipped.scene_file()


def scene_file_or_error(text: str | None) -> str:
    path = scene_file(text)
    if path is None:
        raise ConfigError("no scene file: no ./scenes.yaml, and none shipped with the package; "
                          "give one with --scene-file")
    return str(path)
