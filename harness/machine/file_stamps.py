"""Whether files changed since they were read: what the per-process caches of parsed files
(scene and experiment YAML, shader sources, techniques' code versions) compare before they
hand out what they kept."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable


def stamp(path: str | Path) -> tuple[int, int, int, int]:
    """(device, inode, size, modification time in ns) of a file; OSError when it cannot be
    read. Take it before reading the file: a change after that shows at the next look."""
    s = os.stat(path)
    return s.st_dev, s.st_ino, s.st_size, s.st_mtime_ns


def stamps(paths: Iterable[str | Path]) -> tuple | None:
    """:func:`stamp` of each file, in order; None when one is gone."""
    try:
        return tuple(map(stamp, paths))
    except OSError:
        return None
