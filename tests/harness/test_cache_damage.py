"""Damaged cache entries heal: a mesh or reference entry truncated, with a bit flipped, of the
wrong shape, with NaN or out-of-range values, with faces past the end of its vertices, or a
folder in the entry's place is a miss. The run builds it again, gives the numbers of a run on
a fresh cache, rewrites the entry (verified on the next read) and says so in its manifest.

Which broken version each kind catches (each run once against it, see docs of issue 34):
- truncated, folder: the reader's errors not all taken as a miss (the old reader: BadZipFile
  or IsADirectoryError with a traceback in every run; the folder was never replaced);
- bit flip: the checksum skipped (the entry is otherwise well formed, numbers subtly off);
- wrong shape, NaN, out of range, indices past the end: the invariant checks skipped (their
  checksum is recomputed, so only the invariants see them).
"""

from __future__ import annotations

import io
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml

from harness import cli, results
from harness.truth import reference
from harness.config import cache_entry, mesh_files

# a 48x40 box over a plane; the box is an OBJ file (8 vertices, 12 faces, closed)
BOX_OBJ = "".join(f"v {x} {y} {z}\n" for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (1, 2)) + (
    "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n")
SCENE = {
    "resolution": [48, 40],
    "camera": {"position": [0, -6, 4], "target": [0, 0, 0], "up": [0, 0, 1], "yfov": 60,
               "near": 0.1, "far": 100},
    "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
    "effects": ["shadow"],
    "objects": [{"shape": "plane", "size": [10, 10]}, {"shape": "mesh", "path": "box.obj"}],
}
METRICS = ("mae", "rmse", "wrong_pct", "edge_mae", "ssim", "psnr", "frags_scene", "frags_shadow")


def _run(folder: Path, cache: Path, monkeypatch) -> tuple[dict, dict]:
    """One sm run of the scene with ``cache`` as the cache: its row and its manifest."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(cache))
    monkeypatch.setattr(mesh_files, "_loaded", {})  # this process's memo: read the disk again
    scene_file = folder / "scenes.yaml"
    if not scene_file.exists():
        (folder / "box.obj").write_text(BOX_OBJ)
        scene_file.write_text(yaml.safe_dump({"scenes": {"s": SCENE}}))
    out = folder / "out"
    code = cli.main(["run", "--scene-file", str(scene_file), "--techniques", "sm", "--out",
                     str(out), "--quiet", "--frames", "1", "--warmup", "0"])
    assert code == 0
    (row,) = results.read_rows(out)
    assert row["status"] == "ok", row["error"]
    return row, json.loads((out / "manifest.json").read_text())


@pytest.fixture(scope="module")
def fresh(tmp_path_factory, gl_context):
    """A run on an empty cache: its row and the cache it filled."""
    folder = tmp_path_factory.mktemp("fresh")
    with pytest.MonkeyPatch.context() as monkeypatch:
        row, _ = _run(folder, folder / "cache", monkeypatch)
    return row, folder / "cache"


def _resave(path: Path, change, keep_checksum: bool) -> None:
    """Rewrite the entry with ``change(arrays)`` applied: with its checksum recomputed (only the
    invariants can tell) or the old one kept (only the checksum can)."""
    with np.load(path) as z:
        arrays = {name: z[name] for name in z.files}
    old = arrays.pop(cache_entry.CHECKSUM)
    change(arrays)
    arrays[cache_entry.CHECKSUM] = old if keep_checksum else np.array(cache_entry.checksum(arrays))
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())


def _flip_bit(arrays, entry):
    """One bit that no invariant can see: the lowest exponent bit of a vertex's x (0.5 becomes
    1.0), or a pixel's coverage."""
    name, byte, mask = ("vertices", 4 * 3 * 8 + 6, 0x10) if entry == "mesh" else (
        "covered", arrays["covered"].size // 2, 0x01)
    a = arrays[name].copy()
    a.reshape(-1).view(np.uint8)[byte] ^= mask
    arrays[name] = a


def _set(name, index, value):
    def change(arrays):
        a = arrays[name].copy()
        a[index] = value
        arrays[name] = a
    return change


DAMAGE = {
    "truncated": lambda path, data: path.write_bytes(path.read_bytes()[: path.stat().st_size // 2]),
    "bit_flip": lambda path, data: _resave(
        path, lambda a: _flip_bit(a, "mesh" if data == "vertices" else "reference"),
        keep_checksum=True),
    "wrong_shape": lambda path, data: _resave(
        path, lambda a: a.update({data: a[data].T.copy() if a[data].shape[0] != a[data].shape[1]
                                  else a[data][:-1]}), keep_checksum=False),
    "nan": lambda path, data: _resave(path, _set(data, (0, 0), np.nan), keep_checksum=False),
    "out_of_range": lambda path, data: _resave(
        path, _set(data, (0, 0), 7.0 if data == "visibility" else 1e9), keep_checksum=False),
    "indices_past_the_end": lambda path, data: _resave(
        path, lambda a: _set("faces", (0, 0), len(a["vertices"]))(a), keep_checksum=False),
    "folder": lambda path, data: (path.unlink(), path.mkdir(), (path / "x").write_text("x")),
}
CASES = [("mesh", kind) for kind in DAMAGE] + [
    ("reference", kind) for kind in DAMAGE if kind != "indices_past_the_end"]


@pytest.mark.parametrize("entry, damage", CASES)
def test_a_damaged_cache_entry_is_rebuilt_and_the_run_heals(entry, damage, fresh, tmp_path,
                                                            monkeypatch):
    fresh_row, fresh_cache = fresh
    cache = tmp_path / "cache"
    shutil.copytree(fresh_cache, cache)
    (path,) = (cache / entry).glob("*.npz")
    DAMAGE[damage](path, "vertices" if entry == "mesh" else "visibility")
    row, manifest = _run(tmp_path, cache, monkeypatch)
    assert {k: row[k] for k in METRICS} == {k: fresh_row[k] for k in METRICS}
    notes = manifest["invocations"][-1]["notes"]
    assert len(notes) == 1 and notes[0].startswith(f"rebuilt damaged cache entry {path}: "), notes
    # rewritten: read back whole, checksum and invariants verified
    assert path.is_file() and zipfile.is_zipfile(path)
    if entry == "mesh":
        assert mesh_files._read_cache(path).triangles == 12
    else:
        z = cache_entry.read_entry(path, reference.REFERENCE_ENTRY)
        assert z["visibility"].shape == (40, 48) and 0 <= z["visibility"].min()
