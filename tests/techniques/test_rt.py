"""rt against the other exact answers: sv's point-sampled V on every shipped scene and hard
case, the embree backend's V on the same rays, and the two builders against each other.
Small images (64 x 64): V is compared pixel by pixel on the pixels metrics compare."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from harness import config
from harness.scene import build_scene
from harness.technique import Frame
from helpers import LARGE_SPOTS, ROOT, cut_out, on_a_boundary, technique_visibility

HARD = ROOT / "experiments" / "hard_cases" / "scenes.yaml"
SIZE = 64
# the most differing pixels a scene may have, as a share of its compared pixels: foliage at
# 64 x 64 has 7 of 2272 (0.31%), all on shadow edges of leaves, the reference there 0.59-0.88
TIES = 0.005
# where sv's V is wrong, not a tie: the pixels differ off any edge, and embree's rays agree
# with rt's there
SV_WRONG = {
    # 13 pixels of row 0: the top face (z = 2.98) of the small box that crosses the near
    # plane, nothing above it and the light above: lit; sv's z-fail shades them (its volume
    # clipped at the near plane)
    "hard_near_plane_crossing": 13,
    # 1 pixel of a beam's side face (y normal, z = 0.49) among compas's crossing boxes, whose
    # faces touch and lie in one plane with others': sv's volumes count it lit, rt, ptsv and
    # embree's rays find the beam above it
    "real_beams": 1,
}


def scenes(path: Path) -> list[tuple[Path, str]]:
    return [(path, name) for name in config.load_scenes(path) if name not in LARGE_SPOTS]


ALL = scenes(ROOT / "scenes.yaml") + scenes(HARD)
# sv declines the alpha-tested scenes (rt cuts them out: test_alpha_casters.py)
OPAQUE = [(path, name) for path in (ROOT / "scenes.yaml", HARD)
          for name, scene in config.load_scenes(path).items()
          if not cut_out(scene) and name not in LARGE_SPOTS]


@pytest.fixture(scope="module")
def frames(gl_context):
    made = {}
    yield made
    for frame in made.values():
        frame.release()


def frame_of(frames, path: Path, name: str) -> Frame:
    if (path, name) not in frames:
        declared = config.load_scenes(path)
        frames[(path, name)] = Frame(build_scene(name, declared[name], path)
                                     .with_resolution(SIZE, SIZE))
    return frames[(path, name)]


@pytest.mark.parametrize("path,name", OPAQUE, ids=[n for _, n in OPAQUE])
def test_rt_equals_sv_but_for_ties_on_shadow_edges(path, name, frames):
    """rt's V (compute traversal) equals sv's (z-fail stencil volumes, exact and point-sampled
    at the pixel centre too) on the compared pixels of every shipped scene and hard case, but
    for at most 0.5% of them, each on a shadow boundary of sv's V (a point whose ray grazes a
    silhouette: the two exact methods round differently there), and for sv's own errors
    (``SV_WRONG``, counted, where the embree backend's rays agree with rt's). Run against an origin offset
    of 0 (OFFSET_ULPS 0 in common/ray_offset.glsl) it fails with self-shadowing acne over lit faces
    (castle, crowd, pins ... thousands of pixels off any boundary); against the top level's
    leaves read as instance indices (levels.rebuild_top without ``top.order``) it loses whole
    casters on every scene with several parts."""
    frame = frame_of(frames, path, name)
    sv, _ = technique_visibility(frame, "sv")
    rt, extra = technique_visibility(frame, "rt")
    compared = frame.compared_pixels(frame.arrays.covered)
    differ = (sv != rt) & compared
    assert set(np.unique(rt)) <= {0.0, 1.0}
    if name in SV_WRONG:
        embree, _ = technique_visibility(frame, "rt", {"backend": "embree"})
        assert differ.sum() == SV_WRONG[name]
        assert np.array_equal(embree[differ], rt[differ])
        return
    assert differ.sum() <= TIES * compared.sum() + 1, (int(differ.sum()), int(compared.sum()))
    assert np.array_equal(on_a_boundary(sv, differ), differ), "a difference off any edge"
    # one ray per covered pixel the light reaches (none where the visible side faces away)
    assert compared.sum() <= extra.get("rays", 0) <= frame.arrays.covered.sum()


@pytest.mark.parametrize("path,name", ALL, ids=[n for _, n in ALL])
def test_compute_traversal_equals_embree_but_for_ties(path, name, frames):
    """The compute traversal's V equals the embree backend's (Mitsuba's ray_test on the same
    rays, origins offset by the same bits) on every shipped scene and hard case (measured: no
    pixel differs in any at 64 x 64), but for at most 0.5% of the
    compared pixels, each on a shadow boundary: Mitsuba traces the scene moved next to its
    origin (``reference.mitsuba_origin``), which rounds a grazing ray otherwise. The SAH
    builder's V equals LBVH's bit for bit (the same triangles, any-hit: the tree changes the
    work, never the answer). Fails against embree rays from the unshifted origins (the mask
    lands 1 scene unit away) and against a GL mask read upside down."""
    frame = frame_of(frames, path, name)
    gl, _ = technique_visibility(frame, "rt")
    embree, _ = technique_visibility(frame, "rt", {"backend": "embree"})
    sah, _ = technique_visibility(frame, "rt", {"build": "sah", "leaf_size": 1})
    compared = frame.compared_pixels(frame.arrays.covered)
    differ = (gl != embree) & compared
    assert differ.sum() <= TIES * compared.sum() + 1, int(differ.sum())
    assert np.array_equal(on_a_boundary(gl, differ), differ)
    np.testing.assert_array_equal(sah, gl)


@pytest.mark.parametrize("mask_res, divisor", [("half", 2), ("quarter", 4)])
def test_smaller_masks_trace_fewer_rays_and_differ_only_near_edges(mask_res, divisor, frames):
    """``mask_res: half`` and ``quarter`` trace about 1/4 and 1/16 of full's rays (castle, 64 x
    64), give fractional V (bilinear magnification) and differ from full's V only within
    ``divisor`` pixels of a change in full's V or in coverage: where V is uniform around a
    pixel every ray that magnification reads agrees. Catches quarter traced as half (ratio
    0.25), and a mask texel's ray from a pixel outside its own block (run with the pixel at
    texel x divisor + 3 divisor: both fail)."""
    from scipy import ndimage

    frame = frame_of(frames, ROOT / "scenes.yaml", "castle")
    full, full_extra = technique_visibility(frame, "rt")
    low, low_extra = technique_visibility(frame, "rt", {"mask_res": mask_res})
    ratio = low_extra["rays"] / full_extra["rays"]
    assert 0.7 / divisor ** 2 < ratio < 1.3 / divisor ** 2, ratio
    covered = frame.arrays.covered
    assert len(np.unique(low[covered])) > 2
    changes = on_a_boundary(full, np.ones_like(covered)) | on_a_boundary(
        covered.astype(np.float32), np.ones_like(covered))
    near = ndimage.binary_dilation(changes, structure=np.ones((3, 3), bool),
                                   iterations=divisor)
    differ = (low != full) & covered
    assert differ.any() and not (differ & ~near).any()
