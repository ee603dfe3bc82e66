"""Alpha-tested casters' input (issue 48): the ``alpha`` key, its texture files and the texture
coordinates of mesh files. Each bad input is one line naming the file and key, exit 2, nothing
written; the loaders' texture coordinates follow glTF's convention (v downward: OBJ's and
PLY's flipped)."""

from __future__ import annotations

import base64
import json
import struct

import numpy as np
import pytest
from helpers import assert_one_line, run_cli, scene_with, sweep, write_scenes
from PIL import Image

from harness import config
from harness.config import mesh_files
from harness.scene import build_scene, load_scene

QUAD_OBJ = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0.25 0.75\n"
            "f 1/1 2/2 3/3 4/4\n")


@pytest.fixture(autouse=True)
def fresh_mesh_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(mesh_files, "_loaded", {}, raising=False)


def with_alpha(tmp_path, alpha, **card):
    """A scene file whose object 1 is a card with ``alpha`` (a plane unless ``card`` says)."""
    obj = {k: v for k, v in {"shape": "plane", "size": [2, 2], "translate": [0, 0, 1.5],
                             **card}.items() if v is not None}
    if alpha is not None:
        obj["alpha"] = alpha
    return write_scenes(tmp_path, {"s": scene_with(objects__1=obj)})


def refused(tmp_path, capsys, alpha, *needles, **card):
    code, err = run_cli(sweep(with_alpha(tmp_path, alpha, **card), tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, str(tmp_path / "scenes.yaml"), "scenes.s.objects.1", *needles)
    assert not (tmp_path / "out").exists()
    return err[0]


def png(path, array, mode=None):
    Image.fromarray(array, mode).save(path)
    return path


# --- bad input: one line, exit 2, nothing written ---------------------------------------------

def test_a_missing_texture(tmp_path, capsys):
    """Catches a texture not looked for at load (a traceback at build time)."""
    refused(tmp_path, capsys, {"texture": "leaf.png"}, "alpha.texture", "no such file",
            str(tmp_path / "leaf.png"))


@pytest.mark.parametrize("content, needle", [
    (b"GIF89a not a png", "not a PNG"),
    (b"", "empty file"),
    # the signature and a header chunk cut short
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00", "not a PNG that can be read"),
])
def test_a_texture_that_is_not_a_png(tmp_path, capsys, content, needle):
    """Catches PIL's own error (a traceback, or an image of another format accepted)."""
    (tmp_path / "leaf.png").write_bytes(content)
    refused(tmp_path, capsys, {"texture": "leaf.png"}, "alpha.texture", needle)


def _png_of_size(width: int, height: int) -> bytes:
    """A PNG whose header says width x height (8-bit grey), its data one empty row."""
    import zlib

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0,
                                                             0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0")) + chunk(b"IEND", b""))


@pytest.mark.parametrize("width, height, needle", [
    (0, 4, "zero-sized"), (8193, 1, "over the limit of 8192x8192"),
    (100_000, 100_000, "over the limit"),
])
def test_a_texture_of_no_texels_or_too_many(tmp_path, capsys, width, height, needle):
    """The size comes from the header, before any pixel is decoded (a 10^10-texel header is
    refused at once). Catches a size checked after decoding (PIL's decompression-bomb error,
    or minutes of work)."""
    (tmp_path / "leaf.png").write_bytes(_png_of_size(width, height))
    refused(tmp_path, capsys, {"texture": "leaf.png"}, "alpha.texture", needle)


def test_a_16_bit_texture(tmp_path, capsys):
    """Catches 16-bit values read as if 8-bit."""
    png(tmp_path / "leaf.png", np.full((4, 4), 40000, np.uint16))
    refused(tmp_path, capsys, {"texture": "leaf.png"}, "alpha.texture", "16 bits a channel")


@pytest.mark.parametrize("cutoff", [-0.1, 1.5])
def test_a_cutoff_outside_0_1(tmp_path, capsys, cutoff):
    """Catches a cutoff taken as written."""
    refused(tmp_path, capsys, {"pattern": "disc", "cutoff": cutoff}, "alpha.cutoff")


@pytest.mark.parametrize("alpha, needle", [
    ({"pattern": "stripes"}, "alpha.pattern"),
    ({"cutoff": 0.5}, "either texture"),
    ({"pattern": "disc", "texture": "x.png"}, "either texture"),
    ({"pattern": "disc", "texels": 0}, "texels"),
    ({"pattern": "disc", "size": 4}, "alpha.size"),
])
def test_an_alpha_key_that_says_nothing_usable(tmp_path, capsys, alpha, needle):
    """Catches an unknown pattern, a missing or double source, and unknown keys accepted."""
    refused(tmp_path, capsys, alpha, needle)


def test_a_shape_without_texture_coordinates(tmp_path, capsys):
    """A box has none (trimesh makes none). Catches the alpha ignored on it."""
    refused(tmp_path, capsys, {"pattern": "disc"}, "alpha", "no texture coordinates",
            shape="box", size=[1, 1, 1])


def test_a_mesh_file_without_texture_coordinates(tmp_path, capsys):
    """Catches a mesh with alpha but no vt cut out at uv (0, 0) everywhere."""
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    refused(tmp_path, capsys, {"pattern": "disc"}, "alpha", "no texture coordinates",
            shape="mesh", path="m.obj", size=None)


@pytest.mark.parametrize("face, needle", [
    ("f 1/5 2/2 3/3", "face indexes texture coordinate 5"),
    ("f 1/-9 2/2 3/3", "face indexes texture coordinate -9"),
    ("f 1/x 2/2 3/3", "texture coordinate index 'x' is not an integer"),
])
def test_obj_vt_indices_out_of_range(tmp_path, capsys, face, needle):
    """Refused like a vertex index out of range, naming the line. Catches vt indices read
    past the array (an IndexError) or wrapped by NumPy's negative indexing."""
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                    + face + "\n")
    code, err = run_cli(sweep(with_alpha(tmp_path, {"pattern": "disc"}, shape="mesh",
                                         path="m.obj", size=None), tmp_path / "out"),
                        capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.path", "line 7", needle)
    assert not (tmp_path / "out").exists()


# --- what loads --------------------------------------------------------------------------------

def test_a_texture_file_alpha_or_grey(tmp_path):
    """An RGBA PNG's alpha channel, a grey PNG's grey, an RGB PNG's red, first row at the top.
    Catches the wrong channel (RGBA's red) and rows flipped."""
    rgba = np.zeros((2, 3, 4), np.uint8)
    rgba[..., 0], rgba[..., 3] = 200, [[0, 10, 20], [30, 40, 50]]
    png(tmp_path / "a.png", rgba)
    png(tmp_path / "g.png", np.array([[1, 2], [3, 4]], np.uint8))
    rgb = np.zeros((1, 2, 3), np.uint8)
    rgb[..., 0], rgb[..., 1] = [7, 8], 99
    png(tmp_path / "c.png", rgb)
    assert (config.read_alpha_texture(tmp_path / "a.png") == [[0, 10, 20], [30, 40, 50]]).all()
    assert (config.read_alpha_texture(tmp_path / "g.png") == [[1, 2], [3, 4]]).all()
    assert (config.read_alpha_texture(tmp_path / "c.png") == [[7, 8]]).all()


def test_a_plane_s_texture_coordinates(tmp_path):
    """The image lies on the plane seen from above: its first row along +y, u along +x.
    Catches v upward (the image upside down on the plane)."""
    scene = build_scene("s", config.load_scenes(with_alpha(tmp_path, {"pattern": "disc"}))["s"],
                        tmp_path / "scenes.yaml")
    card = scene.parts[1]
    corners = card.vertices[card.faces].reshape(-1, 3)
    uv = card.texcoords.reshape(-1, 2)
    np.testing.assert_allclose(uv[:, 0], (corners[:, 0] + 1) / 2)
    np.testing.assert_allclose(uv[:, 1], (1 - corners[:, 1]) / 2)
    assert scene.face_mask.tolist() == [-1, -1, 0, 0]


def test_obj_texture_coordinates_flip_v(tmp_path):
    """An OBJ's vt (v upward) load as (u, 1 - v), per face corner, polygons fanned, negative
    (relative) indices too. Catches no flip, and vt taken from the vertex indices."""
    (tmp_path / "m.obj").write_text(QUAD_OBJ + "f -4/-4 -3/-3 -2/-2\n")
    parts = config.mesh_parts(tmp_path / "m.obj")
    expected = np.array([[[0, 1], [1, 1], [1, 0]], [[0, 1], [1, 0], [0.25, 0.25]],
                         [[0, 1], [1, 1], [1, 0]]])
    np.testing.assert_array_equal(parts.texcoords[0], expected)


def test_obj_faces_without_vt_leave_the_part_without_texture_coordinates(tmp_path):
    """A part with a corner that names no vt (``7``, ``7//2``) has none. Catches a 0 read as
    the first vt."""
    (tmp_path / "m.obj").write_text(QUAD_OBJ.replace("f 1/1 2/2 3/3 4/4", "o a\nf 1/1 2/2 3/3\n"
                                                     "o b\nf 1 2 3\no c\nf 1//1 2//1 3//1"))
    parts = config.mesh_parts(tmp_path / "m.obj")
    assert [t is not None for t in parts.texcoords] == [True, False, False]


def test_ply_texture_coordinates_flip_v(tmp_path):
    """A PLY's per-vertex ``s t`` load flipped to v downward. Catches no flip."""
    (tmp_path / "m.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nproperty float s\nproperty float t\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n"
        "0 0 0 0.1 0.2\n1 0 0 0.3 0.4\n0 1 0 0.5 0.9\n3 0 1 2\n")
    parts = config.mesh_parts(tmp_path / "m.ply")
    np.testing.assert_allclose(parts.texcoords[0], [[[0.1, 0.8], [0.3, 0.6], [0.5, 0.1]]],
                               atol=1e-6)


def _gltf(material: dict) -> dict:
    """A hand-written glTF of one triangle with TEXCOORD_0 (0.1, 0.2), (0.3, 0.4), (0.5, 0.9)
    and ``material``."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    uv = np.array([[0.1, 0.2], [0.3, 0.4], [0.5, 0.9]], np.float32)
    blob = positions.tobytes() + uv.tobytes()
    return {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "scene": 0,
            "nodes": [{"mesh": 0}], "materials": [material],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1},
                                        "material": 0}]}],
            "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                         + base64.b64encode(blob).decode()}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                            {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}]}


def test_gltf_texcoord_0_as_written(tmp_path):
    """A glTF's TEXCOORD_0 is already v downward: loaded as written (a hand-written file, so
    trimesh's own flip on load is checked, not assumed). Catches a flip too many."""
    (tmp_path / "m.gltf").write_text(json.dumps(_gltf({"name": "plain"})))
    parts = config.mesh_parts(tmp_path / "m.gltf")
    np.testing.assert_allclose(parts.texcoords[0], [[[0.1, 0.2], [0.3, 0.4], [0.5, 0.9]]],
                               atol=1e-6)
    assert parts.part_cutouts == (-1,)


def _png_bytes(array) -> bytes:
    import io

    buffer = io.BytesIO()
    Image.fromarray(array).save(buffer, format="PNG")
    return buffer.getvalue()


def test_a_gltf_mask_material_cuts_its_part_out(tmp_path):
    """``alphaMode: MASK`` with ``alphaCutoff``: the base colour texture's alpha times the
    factor's, at that cutoff, the texture first row at the top; the scene's part carries it.
    Catches the mask ignored (an opaque part), the texture's red read for its alpha, the
    factor left out, the default cutoff used for the file's."""
    rgba = np.zeros((2, 2, 4), np.uint8)
    rgba[..., 0], rgba[..., 3] = 255, [[0, 100], [200, 255]]
    gltf = _gltf({"name": "leaf", "alphaMode": "MASK", "alphaCutoff": 0.3,
                  "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                           "baseColorFactor": [1, 1, 1, 0.5]}})
    gltf.update(textures=[{"source": 0}], images=[{
        "uri": "data:image/png;base64," + base64.b64encode(_png_bytes(rgba)).decode()}])
    (tmp_path / "m.gltf").write_text(json.dumps(gltf))
    parts = config.mesh_parts(tmp_path / "m.gltf")
    (texture, cutoff, _), = parts.cutouts
    assert parts.part_cutouts == (0,) and cutoff == pytest.approx(0.3)
    np.testing.assert_array_equal(texture, np.rint(np.array([[0, 100], [200, 255]]) * 0.5))
    scenes = config.load_scenes(with_alpha(tmp_path, None, shape="mesh", path="m.gltf",
                                           size=None))
    scene = build_scene("s", scenes["s"], tmp_path / "scenes.yaml")
    assert scene.has_alpha and scene.face_mask.tolist() == [-1, -1, 0]


def test_an_obj_map_d_cuts_its_faces_out(tmp_path):
    """``mtllib`` read for ``map_d`` alone: the faces of a material with one are cut out by
    it (cutoff 0.5), the other faces of the part split off opaque; a map_d that cannot be
    read is counted, its faces opaque. Catches map_d ignored, a whole part cut out by one
    face's material, and an unreadable map_d refusing the file."""
    png(tmp_path / "leaf.png", np.array([[0, 255]], np.uint8))
    (tmp_path / "m.mtl").write_text("newmtl leaf\nmap_d -clamp on leaf.png\n"
                                    "newmtl bark\nKd 1 1 1\nnewmtl lost\nmap_d gone.png\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\n" + QUAD_OBJ.replace(
        "f 1/1 2/2 3/3 4/4\n", "usemtl bark\nf 1/1 2/2 3/3\nusemtl leaf\nf 1/1 3/3 4/4\n"
        "usemtl lost\nf 1/1 2/2 4/4\n"))
    parts = config.mesh_parts(tmp_path / "m.obj")
    assert [len(f) for f in parts.faces] == [2, 1]  # bark and lost opaque; leaf
    assert parts.part_cutouts == (-1, 0)
    (texture, cutoff, name), = parts.cutouts
    assert texture.tolist() == [[0, 255]] and cutoff == 0.5 and "leaf" in name
    assert "1 map_d textures that cannot be read (their faces opaque)" in parts.notes()


def test_the_scene_key_follows_the_texture_bytes(tmp_path):
    """Catches a key of the file's name alone (a changed texture would reuse a reference)."""
    png(tmp_path / "leaf.png", np.full((4, 4), 255, np.uint8))
    scenes = config.load_scenes(with_alpha(tmp_path, {"texture": "leaf.png"}))
    before = build_scene("s", scenes["s"], tmp_path / "scenes.yaml").key
    png(tmp_path / "leaf.png", np.full((4, 4), 0, np.uint8))
    assert build_scene("s", scenes["s"], tmp_path / "scenes.yaml").key != before


def test_an_opaque_scene_s_key_has_no_alpha_term():
    """Shipped opaque scenes keep their keys (their cached references): nothing of ``alpha``
    enters the hashed description. Catches ``alpha: null`` hashed for every object."""
    scene = load_scene("box_plane")
    dumped = scene.config.model_dump(mode="json")
    assert all(obj["alpha"] is None for obj in dumped["objects"])
    import hashlib

    labels = {"description": True, "motion": True, "family": True,
              "objects": {"__all__": {"name", "alpha"}}}
    text = json.dumps(scene.config.model_dump(mode="json", exclude=labels), sort_keys=True)
    assert scene.key == hashlib.sha256(text.encode()).hexdigest()[:16]


def test_direct_lighting_with_cut_outs_is_refused(tmp_path, capsys):
    """The shaded reference (Mitsuba's direct integrator) would shadow through no hole: an
    effect the harness cannot simulate is an error, not a silent approximation. Catches a
    scene with alpha and ``effects: [shadow, direct]`` accepted."""
    scene = scene_with(objects__1={"shape": "plane", "size": [2, 2], "translate": [0, 0, 1.5],
                                   "alpha": {"pattern": "disc"}}, effects=["shadow", "direct"])
    write_scenes(tmp_path, {"s": scene})
    code, err = run_cli(sweep(tmp_path / "scenes.yaml", tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.effects", "cannot simulate alpha-tested casters")
    assert not (tmp_path / "out").exists()


def test_list_says_which_parts_are_cut_out():
    """``shadowbench list --scene`` names each object's cut-out and cutoff; opaque objects'
    lines are as before. Catches a cut-out invisible to the user before a run."""
    from helpers import SCENE_FILE

    from harness.cli.listing import inspect_lines

    ground, card = inspect_lines(SCENE_FILE, "alpha_checker")[1:3]
    assert ground.endswith("2 triangles, 1 parts")
    assert card.endswith("1 parts, 1 parts cut out by pattern checker 8x8 at 0.5")


def test_a_gltf_mask_material_on_a_part_without_texture_coordinates(tmp_path, capsys):
    """The file's own cut-out with nothing to cut by is refused like an ``alpha`` key on such
    a part. Catches the part cut out at uv (0, 0) everywhere, or silently opaque."""
    gltf = _gltf({"name": "leaf", "alphaMode": "MASK"})
    del gltf["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]
    (tmp_path / "m.gltf").write_text(json.dumps(gltf))
    code, err = run_cli(sweep(with_alpha(tmp_path, None, shape="mesh", path="m.gltf",
                                         size=None), tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.path", "material leaf (alphaMode MASK) "
                    "cuts it out, and it has no texture coordinates")
    assert not (tmp_path / "out").exists()
