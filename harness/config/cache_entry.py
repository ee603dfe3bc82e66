"""Config's cache entries, below mesh_files (and used by harness.truth.reference): an entry is one .npz
of named arrays with a blake2b checksum of their contents stored beside them, written whole or
not at all, and read back verified or not at all, as Git and ccache treat their objects.

:func:`read_entry` gives the arrays only when the file loads, holds every array its reader
expects with the dtype and number of dimensions expected, and the checksum matches; the reader
then checks the invariants it relies on (indices in range, finite values, ...). Anything else
is a damaged entry: a miss, built again and rewritten (:func:`write_entry` replaces even a folder
in the entry's place), and one line for the run's manifest (:func:`note_rebuilt`, collected by
:func:`take_rebuilt_notes`). What its builder refuses is never written.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import numpy as np

CHECKSUM = "checksum"


class DamagedEntry(ValueError):
    """A cache entry that exists but cannot be trusted; the message says why, in a few words."""


def checksum(arrays: dict[str, np.ndarray]) -> str:
    """blake2b over each array's name, dtype, shape and bytes, in name order."""
    digest = hashlib.blake2b(digest_size=16)
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        digest.update(memoryview(a.reshape(-1).view(np.uint8)) if a.size else b"")
    return digest.hexdigest()


def read_entry(path: Path, expected: dict[str, tuple[str, int | None]]
               ) -> dict[str, np.ndarray] | None:
    """The arrays of the entry at ``path``, each ``name: (dtype kind, ndim)`` of ``expected``
    (kinds as numpy's ``dtype.kind``: f, i, b, U; ndim None: any); None when there is no entry. A DamagedEntry
    when it is there but unreadable, incomplete, of other dtypes or shapes, or its checksum
    differs."""
    if not os.path.lexists(path):
        return None
    if not path.is_file():
        raise DamagedEntry("not a regular file")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except Exception as e:  # zipfile, zlib, numpy's format: each raises its own kinds
        raise DamagedEntry(f"unreadable ({type(e).__name__})") from None
    stored = arrays.pop(CHECKSUM, None)
    for name, (kind, ndim) in expected.items():
        if name not in arrays:
            raise DamagedEntry(f"no array {name!r}")
        if arrays[name].dtype.kind != kind or ndim not in (None, arrays[name].ndim):
            raise DamagedEntry(f"{name} is {arrays[name].dtype} with {arrays[name].ndim} "
                               f"dimensions, not {kind!r} with {ndim}")
    if stored is None or stored.shape != () or str(stored) != checksum(arrays):
        raise DamagedEntry("checksum mismatch" if stored is not None else "no checksum")
    return arrays


def write_entry(path: Path, arrays: dict, *, compressed: bool = False) -> None:
    """Store ``arrays`` and their checksum at ``path``: written whole to a temporary file of
    this process and renamed over whatever is there (a damaged file, or a folder, which is
    removed first). An OSError when it cannot be written."""
    arrays = {name: np.asarray(a) for name, a in arrays.items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(temporary, "wb") as f:
            (np.savez_compressed if compressed else np.savez)(
                f, **arrays, **{CHECKSUM: np.array(checksum(arrays))})
            f.flush()
            os.fsync(f.fileno())
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


_rebuilt: list[str] = []


def note_rebuilt(path: Path, why: str) -> None:
    """Record that the damaged entry at ``path`` was built again (one line for the manifest)."""
    _rebuilt.append(f"rebuilt damaged cache entry {path}: {why}")


def take_rebuilt_notes() -> list[str]:
    """The lines recorded since the last call, and forget them."""
    notes = _rebuilt[:]
    del _rebuilt[:]
    return notes
