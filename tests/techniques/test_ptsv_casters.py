"""ptsv's casters (techniques/ptsv/casters.py): two triangles that make a planar convex quad cast
one volume, every other triangle its own; V is the same either way (test_ptsv's
test_same_v_as_sv, on every shipped scene and hard case), the work about halves on a mesh of
quads.

Broken versions each test was run against once (and failed):
- the flatness test left out (quad_casters): test_bent_pair_stays_two_triangles (and the
  count on pins: a few of its pairs are not planar);
- the convexity test left out: test_folded_pair_stays_two_triangles;
- the pairs matched by their shared side's two vertices either way round (not the other
  face's side run backwards): test_inconsistent_winding_stays_two_triangles;
- an edge with three faces paired anyway (the partner found without its key's count):
  test_three_faces_on_an_edge_pair_none;
- a quad's fourth side plane left out (ptsv_setup.comp.glsl's loop over three sides):
  test_ptsv's test_same_v_as_sv fails on 22 of the 30 scenes;
- a quad's bounds across the light over its first three corners only: test_same_v_as_sv fails
  on 11 of the 30;
- pairing off (``quads`` ignored): test_quads_halve_the_work_on_pins.
"""

import numpy as np
import pytest
from helpers import SCENE_FILE, render_once

from harness.scene.families import _quad
from techniques.ptsv import PerTriangleShadowVolumes
from techniques.ptsv.casters import NO_CORNER, quad_casters, triangle_casters

RES = 64
FLAT = 1e-6


def _casters(vertices, faces, sides=None):
    sides = np.zeros(len(faces), np.int32) if sides is None else np.asarray(sides)
    return quad_casters(np.asarray(vertices, np.float64), np.asarray(faces), sides, FLAT)


def _area(points: np.ndarray) -> float:
    """A planar polygon's area (corners in order)."""
    return 0.5 * np.linalg.norm(sum(np.cross(points[k], points[(k + 1) % len(points)])
                                    for k in range(len(points))))


def test_grid_pairs_its_quads():
    """A 3 x 2 grid's 12 triangles make 6 quads; each quad's corners go round it in the faces'
    winding (its area is its two triangles'), and every vertex of the grid is a corner."""
    vertices, faces = _quad((0, 0, 0), (3, 0, 0), (0, 0, 2), 3, 2)
    casters, sides = _casters(vertices, faces)
    assert casters.shape == (6, 4) and (casters[:, 3] != NO_CORNER).all()
    assert sides.tolist() == [0] * 6
    for quad in casters:
        corners = vertices[quad.astype(int)]
        assert _area(corners) == pytest.approx(1.0)
        normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
        face = vertices[faces[0]]
        assert normal @ np.cross(face[1] - face[0], face[2] - face[0]) > 0  # same winding
    assert set(casters.ravel().tolist()) == set(range(len(vertices)))


SQUARE = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
PAIR = [[0, 1, 2], [0, 2, 3]]  # sharing the diagonal 0-2, both wound counter-clockwise


def test_square_pair_is_one_quad():
    casters, _ = _casters(SQUARE, PAIR)
    assert casters.shape == (1, 4)
    assert sorted(casters[0].tolist()) == [0, 1, 2, 3]


def test_bent_pair_stays_two_triangles():
    """The fourth corner off the first triangle's plane by twice the flatness: two casters;
    by half of it: one."""
    for lift, count in ((2 * FLAT, 2), (FLAT / 2, 1)):
        bent = [*SQUARE[:3], [0, 1, lift]]
        assert len(_casters(bent, PAIR)[0]) == count


def test_folded_pair_stays_two_triangles():
    """Two triangles on the same side of their shared side, wound consistently (a sheet folded
    onto itself): not a quad."""
    vertices = [[0, 0, 0], [2, 0, 0], [1, 0.5, 0], [1, 0.25, 0]]
    faces = [[0, 1, 2], [1, 0, 3]]
    casters, _ = _casters(vertices, faces)
    assert casters.shape == (2, 4) and (casters[:, 3] == NO_CORNER).all()


def test_inconsistent_winding_stays_two_triangles():
    """The second face wound the other way (its diagonal traversed 2 -> 0, as the first's)."""
    casters, _ = _casters(SQUARE, [[0, 1, 2], [3, 2, 0]])
    assert casters.shape == (2, 4) and (casters[:, 3] == NO_CORNER).all()


def test_three_faces_on_an_edge_pair_none():
    """A side that is the longest of three faces (a non-manifold fin) pairs none of them."""
    vertices = [*SQUARE, [0.5, 0.5, 1.0]]
    faces = [[0, 1, 2], [0, 2, 3], [0, 2, 4][::-1]]
    assert len(_casters(vertices, faces)[0]) == 3


def test_different_sides_stay_two_triangles():
    assert len(_casters(SQUARE, PAIR, sides=[1, -1])[0]) == 2


def test_triangle_casters():
    casters = triangle_casters(np.array(PAIR))
    assert casters.tolist() == [[0, 1, 2, NO_CORNER], [0, 2, 3, NO_CORNER]]
    assert _casters(np.zeros((0, 3)), np.zeros((0, 3), np.int64))[0].shape == (0, 4)


def test_quads_halve_the_work_on_pins(frames):
    """On pins (lathed pins over a ground plane: each band between two profile points is a ring
    of planar quads, the ends fans of triangles) 2,320 triangle volumes become 1,280 casters'
    (the closed pins' faces turned from the light culled either way),
    and the node and sample tests fall by about 45% (measured: 117,000 and 15,300 against
    64,000 and 8,300); V the same (test_same_v_as_sv)."""
    frame = frames(SCENE_FILE, "pins")
    quads = render_once(PerTriangleShadowVolumes(PerTriangleShadowVolumes.Params()), frame).extra
    triangles = render_once(PerTriangleShadowVolumes(PerTriangleShadowVolumes.Params(
        quads=False)), frame).extra
    assert (quads["volumes_queued"], triangles["volumes_queued"]) == (1280, 2320)
    assert quads["triangles_culled"] == triangles["triangles_culled"]
    assert quads["traversal_nodes"] < 0.65 * triangles["traversal_nodes"]
    assert quads["triangle_tests"] < 0.65 * triangles["triangle_tests"]
