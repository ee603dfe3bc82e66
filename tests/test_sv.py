"""sv: shadow volumes in the stencil, alpha and screen buffers (issue 5; Roettger et al. 2002)."""

import dataclasses
import hashlib

import numpy as np
import pytest
import yaml
from conftest import SCENE_FILE
from scipy import ndimage

from harness import config, metrics
from harness.scene import MeshPart, build_scene

RES = 192
SCENES = list(config.load_scenes(SCENE_FILE))
STATE_MACHINES = [{"buffer": b, "normalize": n} for b in ("alpha", "screen")
                  for n in ("rectangles", "max")]


@pytest.mark.parametrize("scene", SCENES)
def test_stencil_zfail_matches_reference(scene, scene_at, evaluate):
    e = evaluate(scene_at(scene, RES), "sv", {"buffer": "stencil", "method": "zfail"})
    assert e.row["status"] == "ok", e.row["error"]
    assert e.row["wrong_pct"] < 0.5
    ref = e.reference.visibility
    wrong = (np.abs(e.visibility - ref) > 0.5) & e.mask
    # every disagreement is at a reference shadow edge (the project's 2-pixel edge band)
    assert not (wrong & ~metrics.edge_band(ref, mask=e.mask)).any()
    assert set(np.unique(e.visibility)) <= {0.0, 1.0}
    assert 0.01 < 1 - e.visibility[e.mask].mean() < 0.95  # there is a shadow to get right


@pytest.mark.parametrize("state_machine", STATE_MACHINES, ids=lambda p: "-".join(p.values()))
@pytest.mark.parametrize("scene", SCENES)
def test_alpha_and_screen_masks_equal_stencil(scene, state_machine, scene_at, evaluate):
    s = scene_at(scene, RES)
    stencil = evaluate(s, "sv", {"buffer": "stencil"}).visibility
    other = evaluate(s, "sv", state_machine)
    assert other.row["status"] == "ok", other.row["error"]
    assert np.array_equal(stencil, other.visibility)


def test_non_convex_volume_drawn_as_one_saturates(scene_at, evaluate):
    """Section 4.2's limit: a ray entering one volume twice clamps at 1, so a pixel another
    volume already shadows falls back to lit. Per-polygon volumes (auto) avoid it."""
    s = scene_at("pins", 256)
    stencil = evaluate(s, "sv", {"buffer": "stencil"}).visibility
    one = evaluate(s, "sv", {"buffer": "alpha", "volumes": "silhouette"})
    per_polygon = evaluate(s, "sv", {"buffer": "alpha"})
    differ = one.visibility != stencil
    assert differ.sum() > 50
    assert (one.visibility[differ] == 1).all() and (stencil[differ] == 0).all()  # lost shadow
    assert "saturate" in one.row["warnings"]
    assert np.array_equal(per_polygon.visibility, stencil)
    # the price: one volume per triangle fills far more
    assert per_polygon.row["frags_shadow"] > 5 * one.row["frags_shadow"]


def test_camera_inside_volume_zpass_wrong_zfail_right(scene_at, evaluate):
    s = scene_at("camera_in_shadow", RES)
    zfail = evaluate(s, "sv", {"method": "zfail"}).row
    zpass = evaluate(s, "sv", {"method": "zpass"}).row
    assert zfail["wrong_pct"] < 0.5
    # the near plane clips the wall's volume: every count is off by one, the mask inverts
    assert zpass["wrong_pct"] > 30


def _geometric_edges(positions, covered, camera_position, relative_jump=0.03):
    """Pixels next to a coverage change or a jump in camera distance (silhouettes, creases)."""
    distance = np.linalg.norm(positions - camera_position, axis=-1)
    lo = ndimage.minimum_filter(np.where(covered, distance, np.inf), size=3)
    hi = ndimage.maximum_filter(np.where(covered, distance, -np.inf), size=3)
    return ~covered | ~np.isfinite(lo) | ~np.isfinite(hi) | (hi - lo > relative_jump * distance)


@pytest.mark.parametrize("scene", ["box_plane", "castle", "crowd"])
def test_half_resolution_mask(scene, scene_at, evaluate):
    s = scene_at(scene, 256)
    full = evaluate(s, "sv", {"mask_res": "full"})
    half = evaluate(s, "sv", {"mask_res": "half"})
    ratio = half.row["frags_shadow"] / full.row["frags_shadow"]
    assert 0.2 < ratio < 0.3
    assert half.row["levels"] > 2  # bilinear magnification: fractional V at shadow edges
    shadow_edges = metrics.edge_band(full.visibility, mask=full.frame_arrays.covered)
    near_edge = ndimage.binary_dilation(
        shadow_edges | _geometric_edges(full.frame_arrays.position, full.frame_arrays.covered,
                                        np.asarray(s.config.camera.position)),
        structure=np.ones((3, 3), bool), iterations=2)
    differ = (half.visibility != full.visibility) & full.mask
    assert differ.any()
    assert not (differ & ~near_edge).any()


def test_volume_counts_box_plane(scene_at, evaluate):
    """Independent count: a box under a generic directional light has 6 silhouette edges,
    3 lit faces (6 near-cap triangles); the 2-triangle plane gives 2 per-triangle volumes of
    3 sides each (+1 cap). Directional volumes meet in one point at infinity: no far cap."""
    s = scene_at("box_plane", 128)
    zpass = evaluate(s, "sv", {"method": "zpass"}).row
    zfail = evaluate(s, "sv", {"method": "zfail"}).row
    assert zpass["silhouette_edges"] == 6 and zpass["volume_count"] == 3
    assert zpass["volume_triangles"] == 6 + 2 * 3
    assert zfail["volume_triangles"] == 6 + 6 + 2 * 4
    assert zfail["volume_vertices"] == 3 * zfail["volume_triangles"]
    assert zfail["overdraw"] == pytest.approx(zfail["frags_shadow"] / zfail["frags_scene"])
    assert zfail["frags_shadow"] > zfail["frags_scene"]  # volumes fill more than the scene
    assert "0:plane: not closed" in zfail["warnings"]
    assert [p["name"] for p in zfail["passes"]] == ["depth", "volumes", "stencil_mask",
                                                    "visibility"]
    screen = evaluate(s, "sv", {"buffer": "screen"}).row
    assert [p["name"] for p in screen["passes"]] == ["depth", "volumes", "normalize",
                                                     "scene_redraw", "visibility"]


# ---- bad geometry: warnings, never a crash ---------------------------------------------

BOX_SCENE = """
resolution: [128, 128]
camera: {position: [0, -6, 4], target: [0, 0, 0.5], up: [0, 0, 1], yfov: 50, near: 0.1, far: 100}
light: LIGHT
objects:
  - {shape: plane, size: [10, 10]}
  - {shape: box, size: [1, 1, 1], translate: [0, 0, 1.5]}
"""


def _scene_with_box(mutate, light="{type: directional, direction: [-0.3, 0.2, -1]}"):
    cfg = config.Scene(**yaml.safe_load(BOX_SCENE.replace("LIGHT", light)))
    base = build_scene("bad_geometry", cfg)
    plane, box = base.parts
    vertices, faces = mutate(box.vertices.copy(), box.faces.copy())
    bad = MeshPart("1:box", vertices.astype(np.float32), faces.astype(np.int32), box.albedo)
    key = hashlib.sha256(base.key.encode() + vertices.tobytes() + faces.tobytes()).hexdigest()
    return dataclasses.replace(base, parts=[plane, bad], key=key[:16])


def _hole(v, f):
    return v, f[:-1]


def _duplicate_vertices(v, f):
    return v[f.reshape(-1)], np.arange(f.size).reshape(-1, 3)


def _zero_area(v, f):
    return v, np.concatenate([f, [[0, 0, 1], [2, 2, 2]]])


@pytest.mark.parametrize("mutate, warning, volumes", [
    (_hole, "not closed", 11 + 2),  # one volume per remaining box triangle, 2 for the plane
    (_duplicate_vertices, "duplicate vertices merged", 3),
    (_zero_area, "zero-area triangles ignored", 3),
])
def test_bad_geometry_warns_and_stays_right(mutate, warning, volumes, evaluate, gl_context):
    e = evaluate(_scene_with_box(mutate), "sv", {})
    assert e.row["status"] == "ok", e.row["error"]
    assert warning in e.row["warnings"]
    assert e.row["volume_count"] == volumes
    assert e.row["wrong_pct"] < 0.5


def test_light_inside_closed_mesh_warns(evaluate, gl_context):
    def grow(v, f):  # a 6-unit box around the spot light at z = 1.5
        return (v - [0, 0, 1.5]) * 6 + [0, 0, 1.5], f

    scene = _scene_with_box(grow, "{type: spot, position: [0, 0, 1.5], target: [0, 0, 0], "
                                  "fov: 170}")
    e = evaluate(scene, "sv", {})
    assert e.row["status"] == "ok", e.row["error"]
    assert "light is inside this closed mesh" in e.row["warnings"]
    assert set(np.unique(e.visibility)) <= {0.0, 1.0}
    # Where the surface faces the light (the plane outside the box), V matches the reference:
    # shadowed. The box's outside faces away from the light; the reference's shadow ray starts
    # on the light's side of such a surface and calls it lit, the volumes call it shadowed.
    a = e.frame_arrays
    to_light = scene.light.to_light(a.position)
    facing = e.mask & (np.einsum("ijk,ijk->ij", a.normal, to_light) > 0)
    assert facing.sum() > 500
    assert metrics.wrong_pct(e.visibility, e.reference.visibility, mask=facing) < 0.5
