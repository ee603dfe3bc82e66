"""Mesh files as exporters write them (issue 32 item 1, issue 34 item 3, issue 35 item 6): what
cannot define a triangle is skipped and counted (in the manifest and each run's
``mesh_notes``), the triangles kept are trimesh's, file normals are never read, and what stays
an error is one line with nothing written. Each test names the broken version it catches."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import trimesh

from harness import config
from harness.config import mesh_files, mesh_obj
from helpers import (assert_one_line, canonical_triangles, run_cli, scene_with, sweep,
                     write_scenes)

STL_RECORD = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attribute", "<u2")])

# every kind of statement exporters write: a quad with v/vt/vn indices, relative (negative)
# indices, 2- and 1-vertex faces, l and p elements, a NaN file normal, a NaN vertex no face
# uses, materials, smoothing groups, an unknown keyword, comments, CRLF line ends
MESSY_OBJ = """# exported by hand\r
mtllib no-such-file.mtl\r
o wall\r
v 0 0 0\r
v 2 0 0\r
v 2 2 0\r
v 0 2 0\r
v nan 0 5\r
vt 0 0\r
vt 1 0\r
vn 0 0 nan\r
s 1\r
usemtl stone\r
f 1/1/1 2/2/1 3/1/1 4/1/1\r
f 1 2\r
l 1 2 3\r
p 1\r
g roof\r
v 0.5 0.5 1\r
v 1.5 0.5 1\r
v 0.5 1.5 1\r
v 1.5 1.5 1.2\r
f -4//1 -3//1 -1//1 -2//1\r
f 8\r
cstype bezier\r
"""
MESSY_SKIPPED = {mesh_obj.SHORT_FACES: 2, "l": 1, "p": 1, "vn": 1, "s": 1,
                 "mtllib": 1, "usemtl": 1, "cstype": 1}


@pytest.fixture(autouse=True)
def fresh_mesh_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(mesh_files, "_loaded", {})


def with_mesh(tmp_path, name: str, content: bytes | str):
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return write_scenes(tmp_path, {"s": scene_with(objects__1={"shape": "mesh", "path": name})})


def ours(path) -> np.ndarray:
    parts = config.mesh_parts(path)
    return canonical_triangles(np.concatenate([v[f] for v, f in zip(parts.vertices, parts.faces)]))


def trimeshs(path) -> np.ndarray:
    mesh = trimesh.load(path, force="mesh", process=False)
    return canonical_triangles(mesh.vertices[mesh.faces])


def test_a_messy_obj_loads_with_its_skips_counted_in_the_manifest_and_the_rows(tmp_path, capsys):
    """Broken versions caught: a 2-vertex face refused (the old loader: 'a face needs 3
    vertices, it has 2') or made a degenerate triangle (trimesh's triangles differ); the file's
    NaN normal read (refused: 'normal is nan'); a NaN vertex no face uses refused; a skipped
    face counted as loaded (the counts differ); the counts sent to stderr, not the rows."""
    scene_file = with_mesh(tmp_path, "m.obj", MESSY_OBJ)
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert code == 0, err
    assert not any("fewer than 3" in line for line in err)
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    mesh, = manifest["scenes"]["s"]["meshes"]
    assert mesh["skipped"] == MESSY_SKIPPED
    assert (mesh["triangles"], mesh["parts"]) == (4, 2)
    with open(tmp_path / "out" / "results.csv", newline="") as f:
        row, = csv.DictReader(f)
    assert row["mesh_notes"] == ("m.obj: skipped 2 faces with fewer than 3 vertices, 1 l, 1 p, "
                                 "1 s, 1 vn, 1 mtllib, 1 cstype, 1 usemtl statements")
    np.testing.assert_array_equal(ours(tmp_path / "m.obj"), trimeshs(tmp_path / "m.obj"))


def test_an_stl_with_nan_and_zero_facet_normals_loads_to_trimeshs_triangles(tmp_path):
    """Broken version caught: facet normals checked or read (the old loader refused 'normal of
    triangle 1 is nan')."""
    sphere = trimesh.creation.icosphere(subdivisions=2)
    records = np.frombuffer(sphere.export(file_type="stl")[84:], STL_RECORD).copy()
    records["normal"][1] = np.nan
    records["normal"][2] = 0
    path = tmp_path / "m.stl"
    path.write_bytes(sphere.export(file_type="stl")[:84] + records.tobytes())
    assert config.mesh_parts(path).triangles == len(sphere.faces) == 320
    np.testing.assert_array_equal(ours(path), canonical_triangles(sphere.vertices[sphere.faces]))


def test_an_off_file_loads_to_trimeshs_triangles(tmp_path):
    """Broken version caught: .off refused as an unknown format (issue 35)."""
    path = tmp_path / "m.off"
    path.write_text("OFF\n# a quad and a triangle\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
                    "0.5 0.5 1\n4 0 1 2 3\n3 0 1 4\n")
    assert config.mesh_parts(path).triangles == 3
    np.testing.assert_array_equal(ours(path), trimeshs(path))


# three objects (o, o, g), the later objects' v lines after the earlier objects' faces; the faces'
# vertex indices left to fill in
OBJ_OF_THREE = """o floor
v 0 0 0
v 4 0 0
v 4 4 0
v 0 4 0
f {}
o wedge
v 1 1 1
v 3 1 1
v 1 3 2
f {}
g roof
v 0 0 3
v 2 0 3
v 0 2 3
v 2 2 4
f {}
f {}
"""
# relative to the vertices read so far (-1: the last one read)
RELATIVE_OBJ = OBJ_OF_THREE.format("-4 -3 -2 -1", "-3 -2 -1", "-4 -3 -1", "-4 -1 -2")
# the same faces counted by hand from the file's first vertex
ABSOLUTE_OBJ = OBJ_OF_THREE.format("1 2 3 4", "5 6 7", "8 9 11", "8 11 10")


def test_relative_indices_count_back_from_the_vertices_read_so_far(tmp_path):
    """Each object's ``f -3 -2 -1`` names its own vertices, though more follow in the file.
    The reference is trimesh's reading of ABSOLUTE_OBJ: trimesh 5.2 reads a negative index from
    the file's last vertex, as Python indexes a list, so its reading of RELATIVE_OBJ is wrong the
    same way as the broken version caught here (counting from the file's last vertex: the floor
    and the wedge made of the roof's vertices)."""
    relative, absolute = tmp_path / "relative.obj", tmp_path / "absolute.obj"
    relative.write_text(RELATIVE_OBJ)
    absolute.write_text(ABSOLUTE_OBJ)
    np.testing.assert_array_equal(ours(relative), trimeshs(absolute))


@pytest.mark.parametrize("content, needle", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n",
     "line 5: face indexes vertex 9, which does not exist (the file has 3 vertices)"),
    ("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 1 0\nf 1 2 4\nf 1 2 3\n", "line 3: vertex is nan"),
    ("v 0 0 0\nv 1 0 0\nf 1 2\nl 1 2\np 1\n",
     "no triangle left (skipped 1 faces with fewer than 3 vertices, 1 l, 1 p statements)"),
    ("v 0 0\nf 1 1 1\n", "line 1: a vertex needs 3 numbers, it has 2"),
])
def test_what_cannot_be_interpreted_stays_one_line_with_nothing_written(content, needle, tmp_path,
                                                                        capsys):
    """Broken versions caught: an index out of range, a NaN vertex a face uses, or a file with
    nothing left after the skips loaded (or refused with a traceback)."""
    scene_file = with_mesh(tmp_path, "m.obj", content)
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1", str(tmp_path / "m.obj"), needle)
    assert not (tmp_path / "out").exists()
    assert not list((tmp_path / "cache").rglob("*.npz"))


def hexagons(count: int, first: int = 1) -> str:
    """``count`` hexagons side by side: 4 triangles each once fanned, one ``f`` line each (their
    vertices numbered from ``first``)."""
    angles = np.arange(6) * np.pi / 3
    centres = np.c_[np.arange(count) * 3.0, np.zeros(count)]
    corners = (centres[:, None, :] + np.c_[np.cos(angles), np.sin(angles)][None]).reshape(-1, 2)
    v = "".join(f"v {x:.3f} {y:.3f} 0\n" for x, y in corners)
    faces = np.arange(6 * count).reshape(count, 6) + first
    return v + "".join("f " + " ".join(map(str, f)) + "\n" for f in faces)


def test_an_obj_over_the_budget_by_its_fanned_polygons_is_refused_before_parsing(tmp_path,
                                                                                 monkeypatch):
    """300 hexagons: 300 ``f`` lines, 1,200 triangles, over a budget of 1,000. Broken versions
    caught: the budget checked against ``f`` lines (the old count: 300, so the file was parsed
    whole and cached); the file parsed before it is counted; the refused mesh cached."""
    scene_file = with_mesh(tmp_path, "m.obj", hexagons(300))
    monkeypatch.setattr(mesh_files, "_build", lambda *a: pytest.fail("the file was parsed"))
    with pytest.raises(config.ConfigError, match=r"declares at least 1,200 triangles, more than "
                                                 r"the budget of 1,000"):
        config.load_scenes(scene_file, triangle_budget=1000)
    assert not (tmp_path / "cache").exists()


@pytest.mark.parametrize("block", [7, 64, 1 << 22])
def test_the_cheap_count_is_the_parse_count_whatever_the_block_size(block, tmp_path, monkeypatch):
    """The count read in blocks, a line split across two, equals the triangles the parse makes
    (fanned, the short faces none). Broken versions caught: a block's last partial line
    dropped or counted twice; short faces counted as triangles."""
    path = tmp_path / "m.obj"
    path.write_text(MESSY_OBJ + hexagons(40, first=10) + "f 1 2\n")
    monkeypatch.setattr(mesh_obj, "SCAN_BLOCK", block)
    parsed, _ = mesh_obj.read_obj(path.read_bytes())
    assert mesh_obj.obj_triangles(path) == sum(len(f) for _, _, f, _, _ in parsed) == 2 + 2 + 160
    assert mesh_obj.obj_triangles(path, stop_after=10) > 10
