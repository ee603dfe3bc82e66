"""Virtual shadow maps (techniques/vsm): the pages marked on the GPU against a NumPy float64
oracle, visibility against sm (and, filtered, pcf) at the same effective resolution, the page
cache under motion, and bad parameters."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from harness import cli, config
from harness.scene import build_scene
from harness.technique import Frame, reset_gl_state
from harness.truth.metrics import receives_light
from helpers import ROOT
from techniques.common.footprint import receivers, texel_ratios
from techniques.pcf import PercentageCloserFiltering
from techniques.sm import ShadowMap
from techniques.vsm import VirtualShadowMap
from techniques.vsm import vsm as vsm_module
from techniques.vsm.levels import (SLANT_FLOORS, choose_levels, coarsening_steps, light_vector,
                                   map_texels, natural_level, pixel_angle)
from techniques.vsm.pages import spatial_order

MOTION_SCENES = ROOT / "experiments" / "motion" / "scenes.yaml"
# A float32 computation of a level or a page index can fall either way within this much of a
# boundary (log2 of the footprint ratio; texels): such pixels are ties, not errors.
LEVEL_TIE = 1e-4
TEXEL_TIE = 1e-2


def run(frame, technique=None, **params):
    """(V, the technique) after update and render on ``frame``; a new technique unless given
    (then left prepared), unfiltered unless ``filter`` is given: the oracles below are
    Williams' test's."""
    own = technique is None
    technique = technique or VirtualShadowMap(VirtualShadowMap.Params(
        **{"filter": "none", **params}))
    if own:
        technique.prepare(frame)
    technique.update(frame)
    output = technique.render(frame)
    reset_gl_state()
    return output, technique


def gpu_pages(technique) -> set[tuple[int, int, int]]:
    """The pages the last render requested, as (level, global x, global y)."""
    levels = technique.levels
    requested = np.flatnonzero(technique.pages.requested())
    found = set()
    for index in requested:
        k = int(np.searchsorted(levels.bases, index, side="right") - 1)
        n, origin = int(levels.pages[k]), levels.origins[k]
        m = np.array([(index - levels.bases[k]) % n, (index - levels.bases[k]) // n])
        g = origin + np.mod(m - origin, n)
        found.add((k, int(g[0]), int(g[1])))
    return found


def oracle_pages(frame, technique, bias: int = 0, reach: float = 0.0,
                 slant_floor: float = SLANT_FLOORS[0]):
    """The (level, global page) sets of the marked pixels in float64: those of pixels clear of
    every boundary, and those a float32 computation may also reach (a tie pixel's levels one
    either side, its texel moved by TEXEL_TIE). With ``reach``, a pixel's pages are those of
    its texel moved ``reach`` texels to each corner (a filter's reads)."""
    levels, a = technique.levels, frame.arrays
    eye = frame.camera.position
    lit = a.covered & receives_light(a.normal, a.position, frame.scene.light, eye)
    points, normals = a.position[lit].astype(np.float64), a.normal[lit].astype(np.float64)
    angle = pixel_angle(frame.camera.proj, frame.height)
    light = light_vector(frame.scene.light)
    k = choose_levels(levels, points, normals, eye, light, angle, bias, slant_floor)
    _, ratio = natural_level(levels, points, normals, eye, light, angle, slant_floor)
    level_tie = np.abs(ratio - np.round(ratio)) < LEVEL_TIE
    for j in range(levels.nested):
        for edge in (levels.page, levels.res[j] - levels.page):
            distance = np.abs(map_texels(levels, np.full(len(points), j), points) - edge)
            level_tie |= distance.min(axis=1) < TEXEL_TIE
    corners = [(-reach, -reach)] + ([(reach, -reach), (-reach, reach), (reach, reach)]
                                    if reach > 0 else [])

    def pages(levels_of, texels, where):
        local = np.floor(texels[where] / levels.page).astype(np.int64)
        g = levels.origins[levels_of[where]] + local
        return {(int(j), int(x), int(y)) for j, (x, y) in zip(levels_of[where], g)}

    def within(texels, levels_of):
        return ((texels >= 0) & (texels < levels.res[levels_of][:, None])).all(axis=1)

    certain, possible = set(), set()
    for corner in corners:
        texel = map_texels(levels, k, points) + corner
        near_page_edge = np.abs(texel / levels.page - np.round(texel / levels.page)) * levels.page
        tie = level_tie | (near_page_edge < TEXEL_TIE).any(axis=1)
        certain |= pages(k, texel, ~tie & within(texel, k))
        for shift in (-1, 0, 1):
            j = np.clip(k + shift, 0, levels.count - 1)
            texels = map_texels(levels, j, points) + corner
            for dx in (-TEXEL_TIE, 0, TEXEL_TIE):
                for dy in (-TEXEL_TIE, 0, TEXEL_TIE):
                    moved = texels + [dx, dy]
                    possible |= pages(j, moved, tie & within(moved, j))
    possible |= certain
    return certain, possible, k[~level_tie]


@pytest.mark.parametrize("filter_name", ["none", "pcf"])
@pytest.mark.parametrize("scene_name, size", [("castle", 96), ("terrain_long", 96),
                                              ("sphere_plane", 64)])
def test_marked_pages_are_the_oracles(scene_name, size, filter_name, gl_context, scene_at):
    """Every pixel whose visible side faces the light marks the page of its texel in the level
    whose texel is the largest not above its footprint (levels.choose_levels in float64, the
    nested windows' edges included), filtered the pages of its texel moved PCF_REACH texels to
    each corner (the filter's reads stay within them): the GPU's set of (level, global page)
    holds every page of the pixels clear of a boundary and nothing a float32 tie could not
    reach. castle and terrain_long (directional: clipmap levels and mips, several in use),
    sphere_plane (a spot light's mips). Catches the level from the wrong footprint (one level
    off: every page at another level) and a filter's reach not marked (pages missing)."""
    frame = Frame(scene_at(scene_name, size))
    reach = vsm_module.PCF_REACH if filter_name == "pcf" else 0.0
    try:
        output, technique = run(frame, virtual_res=4096, page=64, filter=filter_name)
        found = gpu_pages(technique)
        certain, possible, levels_used = oracle_pages(frame, technique, reach=reach)
        technique.release()
    finally:
        frame.release()
    assert output.extra["pages_coarsened"] == 0
    assert len(set(levels_used.tolist())) >= 2, "the scene should use several levels"
    assert certain <= found, sorted(certain - found)[:5]
    assert found <= possible, sorted(found - possible)[:5]


@pytest.mark.parametrize("scene_name, size, share", [("castle", 96, 1 / 3),
                                                     ("instancing", 128, 0.8)])
def test_a_full_pool_coarsens_until_the_pages_fit(scene_name, size, share, gl_context,
                                                  scene_at):
    """With a pool smaller than the natural pages, marking takes the first coarsening step
    (levels.coarsening_steps: the slant's floor raised, then every pixel a level up at a time)
    whose pages fit: the oracle's set at that step fits the pool and the one a step finer does
    not; the GPU marks the oracle's set. castle at 96 x 96 with a third of its pages moves
    whole levels; instancing at 128 x 128 with 80 % only raises the floor (its spheres'
    terminators, edge-on to the light, ask two levels finer at the first floor). Catches an
    overflow that is not coarsened (pages dropped), one coarsened a step too far, or the
    floor's step skipped (a whole level lost for a sliver of pixels)."""
    frame = Frame(scene_at(scene_name, size))
    try:
        _, whole = run(frame, virtual_res=4096, page=64)
        natural = len(gpu_pages(whole))
        whole.release()
        pool = int(natural * share)
        output, technique = run(frame, virtual_res=4096, page=64, pool_pages=pool)
        step = (output.extra["pages_coarsened"], output.extra["slant_floor"])
        steps = coarsening_steps(technique.levels.count)
        found = gpu_pages(technique)
        certain, possible, _ = oracle_pages(frame, technique, step[0], slant_floor=step[1])
        before = steps[steps.index(step) - 1]
        finer, _, _ = oracle_pages(frame, technique, before[0], slant_floor=before[1])
        technique.release()
    finally:
        frame.release()
    if scene_name == "instancing":
        assert step == (0, SLANT_FLOORS[-1])
    else:
        assert step[0] >= 1
    assert steps.index(step) >= 1 and len(found) <= pool < len(finer)
    assert certain <= found <= possible


@pytest.mark.parametrize("scene_name, size", [("box_plane", 64), ("sphere_plane", 96)])
def test_every_requested_page_holds_its_own_page_down_to_the_one_page_mip(
        scene_name, size, gl_context, scene_at):
    """At the defaults, box_plane at 64 x 64 (directional) and sphere_plane at 96 x 96 (spot)
    request pages of the last two mips (2 x 2 pages and one page) together: after a frame
    every requested entry holds a tile and the global page its table place names
    (gpu_pages' index arithmetic in NumPy), the one-page mip's included, and every held entry
    is requested. Catches the level of an entry found by a loop down from the last level that
    each entry leaves at its own (llvmpipe then read the last level as zeros when entries of
    several levels shared a work group: the one-page mip's entry held page (-1, -1) and its
    pixels were all lit)."""
    frame = Frame(scene_at(scene_name, size))
    try:
        _, technique = run(frame)
        found = gpu_pages(technique)
        table, requested = technique.pages.table(), technique.pages.requested()
        levels = technique.levels
        technique.release()
    finally:
        frame.release()
    last = levels.count - 1
    assert {last - 1, last} <= {k for k, _, _ in found}, "the view should use both last mips"
    assert set(np.flatnonzero(table[:, 0] >= 0)) == set(np.flatnonzero(requested))
    held = {(int(np.searchsorted(levels.bases, index, side="right") - 1),
             int(table[index, 1]), int(table[index, 2])) for index in np.flatnonzero(requested)}
    assert held == found, sorted(held ^ found)[:5]


def levels_used(frame, technique) -> np.ndarray:
    """Each pixel's level by the float64 oracle, -1 where a float32 choice may differ."""
    levels, a = technique.levels, frame.arrays
    eye = frame.camera.position
    points = a.position.reshape(-1, 3).astype(np.float64)
    normals = a.normal.reshape(-1, 3).astype(np.float64)
    angle = pixel_angle(frame.camera.proj, frame.height)
    light = light_vector(frame.scene.light)
    k = choose_levels(levels, points, normals, eye, light, angle)
    _, ratio = natural_level(levels, points, normals, eye, light, angle)
    k[np.abs(ratio - np.round(ratio)) < LEVEL_TIE] = -1
    return k.reshape(a.covered.shape)


def same_resolution_map(filter_name: str, res: int):
    """The fixed-map technique a vsm level of ``res`` texels equals: sm unfiltered, pcf with
    vsm's filter (a 4 x 4 grid over half the footprint, at least a quarter texel; one bias)."""
    if filter_name == "none":
        return ShadowMap(ShadowMap.Params(res=res))
    return PercentageCloserFiltering(PercentageCloserFiltering.Params(
        res=res, k=vsm_module.PCF_GRID ** 2, res_factor=vsm_module.PCF_RES_FACTOR,
        min_size=vsm_module.PCF_MIN_SIZE, bias_min=0.02, bias_max=0.02))


@pytest.mark.parametrize("filter_name", ["none", "pcf"])
@pytest.mark.parametrize("scene_name", ["castle", "sphere_plane"])
def test_visibility_equals_sm_at_the_same_effective_resolution(scene_name, filter_name,
                                                               gl_context, scene_at):
    """With one clipmap level (directional: the light's map frustum, sm's, then its mips; a
    spot: its cone's mips) and every page in the pool, a pixel using mip m is tested exactly
    as sm's map of virtual_res / 2^m texels tests it: the same frustum, the same texel grid,
    the same shadow_map.glsl arithmetic; filtered, as pcf's map of that size filters it (the
    same footprint region and reads, across page borders through the table). On the pixels
    the light reaches (the others are V = 0 in vsm, as in rt, and in no comparison) V equals
    sm's (pcf's) there except on ties (a texel centre on a caster's edge rasterised either way
    after the page's remap to its tile) and, filtered, where vsm's region stops at 2 texels a
    side (pcf's at 32): at most 0.2 % of the pixels (1 % filtered; measured 0, and 49 of 9,179
    on castle, 0 of 15,031 on sphere_plane). Catches a page drawn at an
    offset into its tile (every shadow edge moves by a texel), a read of the wrong tile, and a
    filter reading outside the pages marked for it (those reads lit)."""
    frame = Frame(scene_at(scene_name, 128))
    compared = differing = 0
    try:
        output, technique = run(frame, virtual_res=4096, page=64, levels=1, pool_pages=4096,
                                filter=filter_name)
        used = levels_used(frame, technique)
        res = technique.levels.res
        technique.release()
        for k in np.unique(used[frame.arrays.covered]):
            if k < 0 or res[k] < 16:
                continue
            fixed = same_resolution_map(filter_name, int(res[k]))
            fixed.prepare(frame)
            fixed.update(frame)
            v = fixed.render(frame).visibility
            fixed.release()
            reset_gl_state()
            here = receivers(frame) & (used == k)
            compared += here.sum()
            differing += (np.abs(v[here] - output.visibility[here]) > 1e-6).sum()
    finally:
        frame.release()
    assert compared > 0.9 * receivers(frame).sum()
    assert differing <= (0.002 if filter_name == "none" else 0.01) * compared, (differing,
                                                                                 compared)


def motion_frame(name: str, size: int = 96) -> Frame:
    scenes = config.load_scenes(MOTION_SCENES)
    scene = build_scene(name, scenes[name], MOTION_SCENES).with_resolution(size, size)
    return Frame(scene)


# the caster's first and last frames (its orbit's quarter turn apart, so its old shadow lies
# on pages its new box does not reach), 6 frames of the light's and of the camera's orbits
@pytest.mark.parametrize("scene_name, size, frames", [("box_plane_caster", 160, (0, 15)),
                                                      ("box_plane_light", 96, range(0, 48, 8)),
                                                      ("box_plane_camera", 96, range(0, 48, 8))])
def test_cached_frames_equal_fresh_uncached_ones(scene_name, size, frames, gl_context):
    """Along a moving sequence, the cached technique's V at each frame equals a fresh uncached
    technique's on that frame, bit for bit: the box tumbling and orbiting (its pages dropped
    where its old or new box meets them), the light orbiting (every page dropped), the camera
    orbiting over a still scene (only newly marked pages rendered). Where only the caster
    moves, fewer pages are rendered than marked. Catches the moving object's old pose not
    invalidated (its old shadow stays in cached pages)."""
    frame = motion_frame(scene_name, size)
    # filtered (the default), so a page's border reads of a neighbour page are checked too
    cached = VirtualShadowMap(VirtualShadowMap.Params(virtual_res=4096, page=64, filter="pcf"))
    rendered, marked = [], []
    try:
        cached.prepare(frame)
        for t in frames:
            frame.move_to(t)
            output, _ = run(frame, cached)
            fresh, technique = run(frame, virtual_res=4096, page=64, cache=False, filter="pcf")
            technique.release()
            np.testing.assert_array_equal(output.visibility, fresh.visibility, err_msg=f"{t}")
            if t:
                rendered.append(output.extra["pages_rendered"])
                marked.append(output.extra["pages_marked"])
    finally:
        cached.release()
        frame.release()
    if scene_name == "box_plane_light":
        assert rendered == marked
    else:
        assert sum(rendered) < sum(marked)


def test_the_moved_box_holds_the_old_and_the_new_pose(gl_context):
    """The boxes a moved part invalidates hold its vertices at its previous pose and at its
    new one (from the scene's own moved parts). Catches a box from one pose only."""
    frame = motion_frame("box_plane_caster")
    technique = VirtualShadowMap(VirtualShadowMap.Params(virtual_res=4096, page=64))
    try:
        technique.prepare(frame)
        technique.update(frame)
        before = [p.vertices.astype(np.float64) for p in frame.scene.parts]
        frame.move_to(3)
        boxes = technique.moved_boxes(frame.part_poses)
        after = [p.vertices.astype(np.float64) for p in frame.scene.parts]
        technique.release()
    finally:
        frame.release()
    moved = [i for i, (b, a) in enumerate(zip(before, after)) if not np.array_equal(b, a)]
    assert len(boxes) == 2 * len(moved) >= 2
    for (low, high), vertices in zip(boxes, [before[moved[0]], after[moved[0]]]):
        np.testing.assert_allclose(low, vertices.min(axis=0), atol=1e-5)
        np.testing.assert_allclose(high, vertices.max(axis=0), atol=1e-5)


@pytest.mark.parametrize("key, value", [("virtual_res", 6144), ("virtual_res", 2048),
                                        ("page", 96), ("pool_pages", 20000),
                                        ("pool_pages", 0), ("filter", "pcss")])
def test_bad_parameters_exit_2_naming_the_file_and_key(key, value, tmp_path, capsys):
    """virtual_res not a power of two (or below 4096), a page that does not divide it, a pool
    larger than one texture can hold or empty, an unknown filter: exit 2, one line naming the
    experiment file and vsm.<key>, nothing written. Catches a missing check on each."""
    with pytest.raises(ValidationError, match=key):
        VirtualShadowMap.Params(**{key: value})
    experiment = tmp_path / "bad.yaml"
    experiment.write_text(f"techniques:\n  vsm: {{set: {{{key}: {value}}}}}\n")
    out = tmp_path / "out"
    assert cli.main(["run", str(experiment), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.yaml" in err[0] and f"vsm.{key}" in err[0], err
    assert not out.exists()


def test_point_lights_are_declined():
    """A point light is declined with its reason (six virtual maps not built), not rendered
    wrong. Catches declines_lights left at the default or emptied."""
    assert "six" in VirtualShadowMap.declines_lights["point"]
    assert vsm_module.VirtualShadowMap.declines_lights.keys() == {"point"}


def test_spatial_order_keeps_every_face_and_makes_clusters_compact():
    """A 200 x 200 grid of quads (80,000 triangles, in row order as a tessellated ground is
    written): in spatial order every face is kept once, and the boxes of clusters of 64
    consecutive triangles have on average at most half the width + height they have in row
    order (a row-order cluster is a strip 32 quads long, or two rows' ends: 53 quads on
    average; in Z order 20). Width + height is what sets how many pages a box meets (about
    1 + (w + h) / page for a page wider than the box). Catches the order left as written."""
    n = 200
    u, v = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    vertices = np.c_[u.ravel(), v.ravel(), np.zeros(u.size)].astype(np.float32)
    corner = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    faces = np.concatenate([np.c_[corner, corner + n + 1, corner + 1],
                            np.c_[corner + 1, corner + n + 1, corner + n + 2]]).astype(np.uint32)
    faces = faces.reshape(2, -1, 3).transpose(1, 0, 2).reshape(-1, 3)  # quad by quad, row order

    def mean_box_side(order):
        boxes = vertices[order].reshape(-1, 64 * 3, 3)
        extent = boxes.max(axis=1) - boxes.min(axis=1)
        return float((extent[:, 0] + extent[:, 1]).mean())

    ordered = spatial_order(vertices, faces)
    assert sorted(map(tuple, ordered)) == sorted(map(tuple, faces))
    assert mean_box_side(ordered) <= 0.5 * mean_box_side(faces)


@pytest.mark.parametrize("scene_name", ["pins", "jeep", "terrain_long"])
def test_a_pixel_reads_between_half_a_texel_and_two(scene_name, gl_context, scene_at):
    """Issue 49: at the defaults at least 95 % of the receivers read a level whose texel is
    between 0.5 and 2 pixels across on the receiver's plane (footprint.texel_ratios, the
    texels_per_pixel columns' measure, in each pixel's level; measured 99.7 to 100 % at the
    scenes' sizes, 128 x 128 here). Catches the level chosen from the pixel's distance alone
    (tried: 77 % on pins, 82 % on jeep, 51 % on terrain_long, slanted receivers reading texels
    of a third of a pixel; with a rectangular texel's longer side too, 49, 55 and 39 % at the
    scenes' sizes)."""
    frame = Frame(scene_at(scene_name, 128))
    try:
        _, technique = run(frame)
        ratios = texel_ratios(frame, technique.levels.map_grids, technique.level_map(frame))
        technique.release()
    finally:
        frame.release()
    inside = np.mean((ratios >= 0.5) & (ratios <= 2.0))
    assert inside >= 0.95, f"{100 * inside:.1f} % within 0.5 to 2 texels per pixel"
