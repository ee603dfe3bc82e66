"""Mesh files (issue 23 item 2, issue 25's mesh rows): OBJ, PLY, STL and glTF/GLB loaded to the
same triangles, OBJ objects and groups as parts, ``up: y``, the parts cached by content, and
every bad mesh one line (file, scene, key and the file's line or element) with nothing
written. Each bad-input test failed on the code before issue 25 (its docstring says how)."""

from __future__ import annotations

import json
import os
import struct
import time

import numpy as np
import pytest
import trimesh
from helpers import GOOD, assert_one_line, run_cli, scene_with, sweep, write_scenes

from harness import cli, config
from harness.config import mesh_files
from harness.scene import build_scene

STL_RECORD = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attribute", "<u2")])


@pytest.fixture(autouse=True)
def fresh_mesh_cache(tmp_path, monkeypatch):
    """Each test's own mesh cache and in-process memo: cold means cold."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(mesh_files, "_loaded", {}, raising=False)


def with_mesh(tmp_path, name: str, **options):
    """A scene file whose object 1 is the mesh file ``name`` (in tmp_path)."""
    return write_scenes(tmp_path, {"s": scene_with(objects__1={
        "shape": "mesh", "path": name, **options})})


def bad_mesh(tmp_path, capsys, name: str, content, *needles, **options):
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    code, err = run_cli(sweep(with_mesh(tmp_path, name, **options), tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1", str(path), *needles)
    assert not (tmp_path / "out").exists()
    return err[0]


def binary(mesh: trimesh.Trimesh, fmt: str) -> bytes:
    return mesh.export(file_type=fmt)


TRIANGLE = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                           [[0, 1, 2], [0, 1, 3]], process=False)


def with_vertex(value) -> trimesh.Trimesh:
    vertices = TRIANGLE.vertices.copy()
    vertices[3, 1] = value
    return trimesh.Trimesh(vertices, TRIANGLE.faces, process=False)


# --- issue 25's rows -------------------------------------------------------------------------

def test_a_nan_vertex_in_an_obj_names_its_line(tmp_path, capsys):
    """Before: accepted silently (trimesh dropped the face with the NaN vertex)."""
    bad_mesh(tmp_path, capsys, "m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n# x\nv nan 0 1\n"
             "f 1 2 3\nf 1 2 4\n", "line 5: vertex is nan")


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")  # trimesh writing the file
@pytest.mark.parametrize("fmt", ["ply", "glb", "stl"])
@pytest.mark.parametrize("value, word", [(np.nan, "nan"), (np.inf, "inf")])
def test_a_nan_or_inf_vertex_names_the_vertex(fmt, value, word, tmp_path, capsys):
    """Before: 'no triangles' (trimesh had dropped them all) or accepted."""
    vertex = "vertex 5 (triangle 1)" if fmt == "stl" else "vertex 3"
    bad_mesh(tmp_path, capsys, f"m.{fmt}", binary(with_vertex(value), fmt), f"{vertex} is {word}")


def test_an_obj_whose_triangles_are_all_degenerate(tmp_path, capsys):
    """Before: it ran, and scikit-image's psnr warning (divide by zero) was printed among the
    progress lines."""
    bad_mesh(tmp_path, capsys, "m.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n",
             "all 2 triangles are degenerate")


def test_coordinates_of_1e30_are_one_line_with_no_library_warning(tmp_path, capsys):
    """Before: refused, but trimesh's RuntimeWarning printed 2 lines above the error."""
    bad_mesh(tmp_path, capsys, "m.obj", "v 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n",
             "line 2: vertex has coordinate 1e+30")


@pytest.mark.parametrize("fmt", ["stl", "ply", "glb", "obj"])
def test_a_mesh_over_the_budget_is_refused_from_its_header_at_once(fmt, tmp_path, monkeypatch):
    """Before: a 5.2 M-triangle STL was loaded whole (48 s, 3.6 GB) before it was counted.
    Here the budget is 1,000 and the file 20,480 triangles; the load is never reached."""
    mesh = trimesh.creation.icosphere(subdivisions=5)
    (tmp_path / f"m.{fmt}").write_bytes(binary(mesh, fmt) if fmt != "obj"
                                        else mesh.export(file_type="obj").encode())
    monkeypatch.setattr(trimesh, "load", lambda *a, **k: pytest.fail("the file was loaded"))
    monkeypatch.setattr(mesh_files, "_build", lambda *a: pytest.fail("the file was loaded"))
    started = time.monotonic()
    with pytest.raises(config.ConfigError, match=r"declares (at least )?20,480 triangles, more than the "
                                                 r"budget of 1,000"):
        config.load_scenes(with_mesh(tmp_path, f"m.{fmt}"), triangle_budget=1000)
    assert time.monotonic() - started < 1


@pytest.mark.parametrize("cut", [30, -1])
def test_an_stl_whose_header_lies_says_what_it_declares_and_holds(cut, tmp_path, capsys):
    """Before: 'not a mesh file trimesh can read'."""
    data = binary(TRIANGLE, "stl")
    if cut > 0:
        data = data[:-cut]
    else:
        data = data[:80] + struct.pack("<I", 5_200_000) + data[84:]
    held = "1 and 20 bytes more" if cut > 0 else "2"
    declared = "2" if cut > 0 else "5,200,000"
    bad_mesh(tmp_path, capsys, "m.stl", data, f"declares {declared} triangles, the file "
                                              f"holds {held}")


@pytest.mark.parametrize("kind", ["FIFO", "folder"])
def test_a_mesh_path_that_is_not_a_regular_file(kind, tmp_path, capsys):
    """Before: a FIFO was reported as 'no such file'."""
    path = tmp_path / "m.obj"
    os.mkfifo(path) if kind == "FIFO" else path.mkdir()
    code, err = run_cli(sweep(with_mesh(tmp_path, "m.obj"), tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.path", f"not a regular file: it is a "
                                                             f"{kind}")


# --- issue 23's bad input ---------------------------------------------------------------------

@pytest.mark.parametrize("fmt, needle", [("obj", "line 5: face indexes vertex 9, which does "
                                                  "not exist (the file has 3 vertices)"),
                                         ("ply", "face 1 indexes vertex 7, and there are 3"),
                                         ("glb", "face 1 indexes vertex 7, and there are 3")])
def test_faces_that_index_missing_vertices_are_named(fmt, needle, tmp_path, capsys):
    """Before: trimesh's IndexError ('index 8 is out of bounds'), or accepted (PLY, GLB)."""
    if fmt == "obj":
        content = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n"
    else:
        content = binary(trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                                         [[0, 1, 2], [0, 1, 7]], process=False), fmt)
    bad_mesh(tmp_path, capsys, f"m.{fmt}", content, needle)


def test_a_gltf_with_no_triangles(tmp_path, capsys):
    points = trimesh.Scene(trimesh.PointCloud([[0, 0, 0], [1, 1, 1]]))
    bad_mesh(tmp_path, capsys, "m.glb", points.export(file_type="glb"), "glTF with no "
                                                                        "triangles")


def test_up_x_is_bad_input(tmp_path, capsys):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code, err = run_cli(sweep(with_mesh(tmp_path, "m.obj", up="x"), tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.up", "'y' or 'z'")


# --- what loads ------------------------------------------------------------------------------

def _lattice_mesh() -> trimesh.Trimesh:
    """Two closed boxes at half-integer coordinates, exact in every format's numbers."""
    a = trimesh.creation.box(extents=[1, 2, 3])
    b = trimesh.creation.box(extents=[2, 1, 1])
    b.apply_translation([3, 0.5, 1])
    return trimesh.util.concatenate([a, b])


def _triangles(path, **options) -> np.ndarray:
    obj = config.MeshFile(shape="mesh", path=str(path), **options)
    scene = config.Scene(camera={"position": [0, -9, 6], "target": [0, 0, 0]},
                         light={"type": "directional", "direction": [0, 0, -1]}, objects=[obj])
    triangles = build_scene("s", scene, path.parent / "scenes.yaml").triangles
    return triangles[np.lexsort(triangles.reshape(len(triangles), -1).T[::-1])]


def test_the_same_mesh_as_obj_ply_stl_and_glb_loads_to_the_same_triangles(tmp_path):
    mesh = _lattice_mesh()
    loaded = {}
    for fmt in ("obj", "ply", "stl", "glb"):
        (tmp_path / f"m.{fmt}").write_bytes(binary(mesh, fmt) if fmt != "obj"
                                            else mesh.export(file_type="obj").encode())
        loaded[fmt] = _triangles(tmp_path / f"m.{fmt}")
    assert loaded["obj"].shape == (24, 3, 3)
    for fmt in ("ply", "stl", "glb"):
        np.testing.assert_array_equal(loaded[fmt], loaded["obj"], err_msg=fmt)


def test_obj_objects_and_groups_are_parts_and_each_is_closed_or_not(tmp_path):
    box = trimesh.creation.box()
    vertices = "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in box.vertices)
    faces = "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in box.faces)
    (tmp_path / "m.obj").write_text(f"o closed_box\n{vertices}{faces}g open_half\n"
                                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n"
                                              for a, b, c in box.faces[:6])
                                    + "f 1 1 2\n")
    parts = config.mesh_parts(tmp_path / "m.obj")
    assert parts.names == ("closed_box", "open_half")
    assert parts.closed == (True, False)
    assert [len(f) for f in parts.faces] == [12, 6]
    assert parts.dropped == 1


def test_up_y_turns_the_files_y_axis_to_z(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n")
    z_up, y_up = _triangles(tmp_path / "m.obj"), _triangles(tmp_path / "m.obj", up="y")
    np.testing.assert_array_equal(z_up[0], [[0, 0, 0], [1, 0, 0], [0, 2, 0]])
    np.testing.assert_array_equal(y_up[0], [[0, 0, 0], [1, 0, 0], [0, 0, 2]])


def test_a_cached_scene_equals_a_freshly_built_one_bit_for_bit(tmp_path, monkeypatch):
    mesh = trimesh.creation.icosphere(subdivisions=3)
    mesh.vertices += np.random.default_rng(1).normal(0, 1e-3, mesh.vertices.shape)
    (tmp_path / "m.ply").write_bytes(binary(mesh, "ply"))
    fresh = config.mesh_parts(tmp_path / "m.ply")
    cached_files = list((tmp_path / "cache" / "mesh").glob("*.npz"))
    assert len(cached_files) == 1
    mesh_files._loaded.clear()
    monkeypatch.setattr(mesh_files, "_build", lambda *a: pytest.fail("built again"))
    cached = config.mesh_parts(tmp_path / "m.ply")
    assert cached.names == fresh.names and cached.closed == fresh.closed == (True,)
    for a, b in zip(cached.vertices + cached.faces, fresh.vertices + fresh.faces):
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_a_damaged_cache_file_is_a_miss(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    first = config.mesh_parts(tmp_path / "m.obj")
    (cached,) = (tmp_path / "cache" / "mesh").glob("*.npz")
    cached.write_bytes(b"damaged")
    mesh_files._loaded.clear()
    again = config.mesh_parts(tmp_path / "m.obj")
    assert again.faces[0].tolist() == first.faces[0].tolist() == [[0, 1, 2]]


def test_degenerate_triangles_among_good_ones_are_dropped_and_counted(tmp_path, capsys):
    """In `shadowbench list` and in the manifest."""
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n"
                                    "f 1 2 3\nf 1 2 4\nf 3 3 1\n")
    scene_file = with_mesh(tmp_path, "m.obj")
    assert cli.main(["list", "--scene-file", str(scene_file)]) == 0
    assert "mesh m.obj: 1 triangles in 1 parts (1 open), 2 degenerate dropped" in \
        capsys.readouterr().out
    plan = __import__("harness.run", fromlist=["plan_runs"]).plan_runs(
        experiment_path=None, scene_file=str(scene_file), scenes=None, techniques=["sm"],
        overrides={})
    from harness.run.manifest import _meshes

    (_, config, source), = plan.described()
    assert _meshes(config, source) == [{"path": "m.obj", "triangles": 1, "parts": 1,
                                        "open_parts": 1, "degenerate_dropped": 2,
                                        "skipped": {}}]
    json.dumps(_meshes(config, source))  # as the manifest stores it


@pytest.mark.parametrize("obj", [
    {"shape": "plane"}, {"shape": "box"},
    *({"shape": "sphere", "subdivisions": s} for s in (1, 3, 5)),
    *({"shape": "cylinder", "sections": n} for n in (3, 32, 256)),
    *({"shape": "capsule", "sections": n} for n in (3, 16, 128)),
    {"shape": "lathe", "profile": [[0.5, 0], [1, 0.5], [0.5, 1]], "sections": 7},
    {"shape": "lathe", "profile": [[0, 0], [1, 0], [0, 1]], "sections": 24},
])
def test_triangle_counts_are_trimeshs(obj):
    """The budget counts without building: each shape's formula against the mesh trimesh
    builds (an independent count); a lathe's is an upper bound, exact without a radius 0
    (trimesh drops the degenerate triangles there). Catches: a wrong formula (e.g. a capsule
    counted as 2n triangles, not 2n^2)."""
    from harness.scene import build_parts

    scene = config.Scene.model_validate({**GOOD, "objects": [obj]})
    built = sum(len(p.faces) for p in build_parts(scene))
    if any(r == 0 for r, _ in obj.get("profile", [(1, 0)])):
        assert built < scene.objects[0].triangles()
    else:
        assert scene.objects[0].triangles() == built


@pytest.mark.parametrize("make, needle", [
    (lambda p: p.mkdir(), "not a regular file: it is a folder"),
    (lambda p: p.write_bytes(bytes(range(256)) * 8), "not a mesh file"),
    (lambda p: p.write_text("v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), "beyond +-1e+07"),
    (lambda p: p.write_text("v 0 0 0\nf 1 2 9\n"), "cannot load mesh"),
])
def test_mesh_files_that_are_not_meshes(make, needle, tmp_path, capsys):
    """Before: a folder said 'no such file'; random bytes said "No module named
    'charset_normalizer'"; a vertex at 1e39 (inf in float32) was accepted."""
    make(tmp_path / "m.obj")
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1={"shape": "mesh",
                                                                      "path": "m.obj"})})
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.path", needle)
    assert "charset_normalizer" not in err[0]


def test_a_bad_mesh_blocks_only_its_own_scene(tmp_path, capsys):
    """A scene file whose scene ``bad`` names a mesh that does not exist: ``--scenes good``,
    an experiment of ``good`` and ``load_scene("good")`` work; choosing ``bad`` (or every
    scene) is one line naming its path, exit 2. Broken version caught (the old behaviour):
    every scene's meshes checked at load, so ``--scenes good`` exited 2 on bad's path."""
    from harness.scene import load_scene

    (tmp_path / "m.obj").write_text("v 0 0 1\nv 1 0 1\nv 0 1 1\nf 1 2 3\n")
    scene_file = write_scenes(tmp_path, {
        "good": scene_with(objects__1={"shape": "mesh", "path": "m.obj"}),
        "bad": scene_with(objects__1={"shape": "mesh", "path": "missing.obj"})})
    code, err = run_cli(["plan", "--scene-file", scene_file, "--scenes", "good",
                         "--techniques", "sm"], capsys)
    assert code == 0 and err == [], err
    experiment = tmp_path / "good.yaml"
    experiment.write_text("scenes: [good]\ntechniques: {sm: {}}\n")
    code, err = run_cli(["plan", experiment, "--scene-file", scene_file], capsys)
    assert code == 0 and err == [], err
    assert load_scene("good", scene_file).triangles.shape[0] == 3  # plane 2 + the mesh's 1
    for args in (["--scenes", "bad"], []):
        code, err = run_cli(sweep(scene_file, tmp_path / "out", *args), capsys)
        assert_one_line(code, err, 2, f"{scene_file}:", "scenes.bad.objects.1.path",
                        "no such file")
    assert not (tmp_path / "out").exists()
    with pytest.raises(config.ConfigError, match="scenes.bad.objects.1.path"):
        load_scene("bad", scene_file)


def test_list_shows_every_scene_and_the_one_it_cannot_load(tmp_path, capsys):
    """``list`` on a file whose scene ``bad`` names a missing mesh lists ``good`` with its
    mesh, and ``bad`` with the one-line reason, exit 0. Broken version caught (the old
    behaviour): every scene's meshes checked before listing, so ``list`` exited 2 and listed
    no scene."""
    (tmp_path / "m.obj").write_text("v 0 0 1\nv 1 0 1\nv 0 1 1\nf 1 2 3\n")
    scene_file = write_scenes(tmp_path, {
        "good": scene_with(objects__1={"shape": "mesh", "path": "m.obj"}),
        "bad": scene_with(objects__1={"shape": "mesh", "path": "missing.obj"})})
    assert cli.main(["list", "--scene-file", str(scene_file)]) == 0
    out = capsys.readouterr().out.splitlines()
    good, bad = (next(i for i, line in enumerate(out) if line.split()[:1] == [name])
                 for name in ("good", "bad"))
    assert out[good + 1].strip().startswith("mesh m.obj: 1 triangles"), out[good + 1]
    assert "CANNOT LOAD" in out[bad + 1] and "scenes.bad.objects.1.path" in out[bad + 1]
    assert "no such file" in out[bad + 1]


COLLADA = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="quad"><mesh>
    <source id="p"><float_array id="pa" count="12">0 0 0 1 0 0 1 1 0 0 1 0</float_array>
      <technique_common><accessor source="#pa" count="4" stride="3"><param name="X"
        type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor>
      </technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="2"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2 0 2 3</p>
    </triangles></mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s">
    <node id="raised"><translate>0 0 2</translate><instance_geometry url="#quad"/></node>
    <node id="ground"><instance_geometry url="#quad"/></node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


def test_a_collada_file_loads_each_placed_node_as_a_part(tmp_path):
    """A .dae (COLLADA, through trimesh and pycollada) as the docs promise of every format
    trimesh reads: one quad placed by two nodes, one raised by its transform. Broken version
    caught (the old behaviour): ``unknown mesh format '.dae'``."""
    (tmp_path / "quads.dae").write_text(COLLADA)
    scene_file = with_mesh(tmp_path, "quads.dae")
    assert config.load_scenes(scene_file, triangle_budget=1000)["s"]
    parts = config.mesh_parts(tmp_path / "quads.dae")
    assert parts.triangles == 4 and len(parts.names) == 2
    heights = sorted(float(v[:, 2].max()) for v in parts.vertices)
    assert heights == [0.0, 2.0]


def test_a_collada_file_over_the_budget_is_refused_from_its_counts(tmp_path, capsys):
    """Its ``<triangles count=...>`` and ``<instance_geometry>`` are read before the file is
    loaded: a quad of 2 triangles placed twice, 4, against a budget of 3 (an experiment's
    triangle_budget) is refused."""
    (tmp_path / "quads.dae").write_text(COLLADA)
    scene_file = with_mesh(tmp_path, "quads.dae")
    with pytest.raises(config.ConfigError, match=r"quads.dae declares at least 4 triangles, "
                                                 r"more than the budget of 3"):
        config.load_scenes(scene_file, triangle_budget=3)
