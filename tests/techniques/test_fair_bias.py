"""Fair bias (issue 12, items 1-3; issue 14, item 13): every map technique's depth bias follows
its own sampling footprint (receiver-plane bias, techniques/common/shadow_map.glsl), PCF's region is
the pixel's footprint, and acne and leaks are measured apart (harness.truth.metrics)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

from harness.truth import metrics
from helpers import ROOT

SHIPPED = ("sphere_plane", "box_plane", "pins", "castle", "crowd", "terrain_long", "slant_edge",
           "silhouette_hard", "camera_in_shadow", "jeep")
MAPS = (256, 1024, 4096)
FILTERED = ("pcf", "mdsm", "silhouette")
# the real corpus (issue 32: files shipped in packages; issue 46: the user meshes), at its own
# 512 x 384 and every map size (issue 46: the defaults must hold where no tuning ran, at each
# point of the curve the tuner searches): 120 runs, about a minute more on 2 busy cores
CORPUS = ("real_airplane", "real_airplane_spot", "real_plates", "real_plates_spot",
          "real_vault", "real_vault_spot", "real_monkey", "real_monkey_spot", "real_beams",
          "real_beams_spot", "real_torso", "real_torso_spot")
CORPUS_MAP = 1024

# The runs that miss the issue's bar at the defaults, and why. No other default serves them
# without breaking others (measured): slope_bias 0.5 puts pcf's acne above 1 % at map 1024 on
# box_plane, castle, crowd, jeep and camera_in_shadow and leaves MDSM's leaks as they are;
# slope_bias 4 leaves the acne of these runs above 0.1 % except on jeep and terrain_long,
# whose leaks stay.
RESOLUTION = ("a texel covers 2-5 pixels of this view: the map's own jaggies reach past the "
              "2-pixel edge band (sm's half texel already reaches 0.14 % acne on "
              "camera_in_shadow; pcf 0.33 %, 1.49 % with the one-texel region before issue 46)")
WINDOW = ("MDSM's extra depths come from the q-texel window, so its soft edge reaches the "
          "window plus the kernel (about 1.5 texels with the 2 x 2 pair, 2.5 with the 3 x 3 "
          "before issue 46) beyond the shadow boundary, past the 2-pixel band where a texel "
          "covers a pixel or more: Pagot et al.'s semantics, as wide with slope_bias 0")
TERRAIN = ("terrain_long puts an 840-unit plane in one map: texels of 17-270 pixels near the "
           "camera and sub-texel boxes; sm misses the bar too (acne 1.2 % at map 1024), this "
           "is the warps' scene")
CORPUS_WINDOW = (WINDOW + "; on the corpus at map 256 (a texel covers 2 to 4 pixels of the "
                 "512 x 384 views) leaks 0.36 to 2.4 % beyond sm's, and on Suzanne under the "
                 "sun 0.45 % acne, where the 3 x 3 pair left leaks of 0.6 to 6.7 % and acne of "
                 "0.2 to 1.2 % (acne under the spots at most 0.19 % now)")
EXCEPTIONS = {
    **{("terrain_long", res, t): TERRAIN for res in MAPS for t in FILTERED},
    ("camera_in_shadow", 256, "pcf"): RESOLUTION,
    **{(s, 256, "mdsm"): WINDOW for s in SHIPPED if s not in ("box_plane", "slant_edge")},
    **{(s, 1024, "mdsm"): WINDOW for s in ("camera_in_shadow", "castle")},
    **{(s, 256, "mdsm"): CORPUS_WINDOW for s in (
        "real_airplane_spot", "real_plates", "real_plates_spot", "real_vault_spot", "real_monkey",
        "real_beams", "real_beams_spot", "real_torso", "real_torso_spot")},
}
del EXCEPTIONS["terrain_long", 4096, "silhouette"]  # meets the bar


@pytest.fixture(scope="module")
def fair_runs(gl_context, scene_at):
    """(scene, map, technique) -> (acne_pct, leak_pct) at the defaults, shipped 512 x 512 views;
    one frame and one reference per scene. About 40 s on 2 busy cores: the map passes and
    shader builds cost more than the pixels, so the shipped size costs no more than 256."""
    from harness.technique import registry
    from harness.truth.reference import compute_reference
    from harness.technique import Frame, reset_gl_state

    runs = {}
    for name in SHIPPED + CORPUS:
        scene = scene_at(name, 512, 384 if name in CORPUS else 512)
        reference = compute_reference(scene, samples=16)
        frame = Frame(scene)
        mask = frame.compared_pixels(reference.covered)
        band = metrics.edge_band(reference.visibility, mask=mask)
        try:
            for res in MAPS:
                for technique in ("sm", *FILTERED):
                    cls = registry.get(technique)
                    run = cls(cls.Params(res=res))
                    run.prepare(frame)
                    run.update(frame)
                    frame.meter.new_frame(measuring=True)
                    v = run.render(frame).visibility
                    run.release()
                    reset_gl_state()
                    runs[name, res, technique] = tuple(
                        score(v, reference.visibility, mask=mask, band=band)
                        for score in (metrics.acne_pct, metrics.leak_pct, metrics.edge_mae))
        finally:
            frame.release()
    return runs


@pytest.mark.parametrize("technique", FILTERED)
@pytest.mark.parametrize("scene_name, res", [(s, r) for s in SHIPPED + CORPUS for r in MAPS])
def test_defaults_leave_no_acne_and_no_leak_beyond_sm(fair_runs, scene_name, res, technique):
    """Issue 12: at its defaults a technique shows acne_pct <= 0.1 and leak_pct <= sm's + 0.1
    on every shipped scene and map size; issue 32: <= 0.3 and sm's + 0.3 on the real corpus at
    map 1024. EXCEPTIONS lists where that cannot hold and why; an
    exception that starts meeting the bar fails here too, so the list stays true. Catches a
    slope term lost or too small (pcf at 1024 on castle, crowd, jeep: acne; silhouette on the
    box face), or too large (leaks beyond sm's)."""
    acne, leak, _ = fair_runs[scene_name, res, technique]
    sm_leak = fair_runs[scene_name, res, "sm"][1]
    bar = 0.3 if scene_name in CORPUS else 0.1  # issue 32's target on real files
    meets = acne <= bar and leak <= sm_leak + bar
    reason = EXCEPTIONS.get((scene_name, res, technique))
    if reason is None:
        assert meets, f"acne {acne:.3f} %, leak {leak:.3f} % (sm {sm_leak:.3f} %)"
    else:
        assert not meets, f"now meets the bar (acne {acne:.3f}, leak {leak:.3f}): drop the exception"


@pytest.mark.parametrize("scene_name, res", [(s, r) for s in SHIPPED + CORPUS for r in MAPS])
def test_pcf_edges_are_no_worse_than_sm(fair_runs, scene_name, res):
    """Issue 46 item 5: pcf's filter exists to improve edges, so at its defaults its edge_mae
    is at most sm's at the same map size, on every shipped scene and every real-corpus scene.
    Measured at the region of half the pixel's footprint, at least a quarter texel: pcf's
    edge_mae is 0.32 to 0.99 of sm's on these 60 runs. Catches the region at its earlier
    default (res_factor 1, min_size 1 texel): worse than sm on 25 of the 60, up to 1.31 x
    (every corpus scene and seven shipped ones at map 256, where a texel covers pixels and a
    texel's blur passes the pixel; the vault at 1024 and 4096, Suzanne under the spot at 4096,
    camera_in_shadow and castle at 1024, terrain_long at 4096, where the footprint's bounding
    box, wider than a slanted footprint, blurs past the pixel)."""
    pcf_edge, sm_edge = fair_runs[scene_name, res, "pcf"][2], fair_runs[scene_name, res, "sm"][2]
    assert pcf_edge <= sm_edge, f"pcf {pcf_edge:.4f}, sm {sm_edge:.4f}"


@pytest.mark.parametrize("scene_name, res", [(s, r) for s in CORPUS if s.endswith("_spot")
                                              for r in MAPS])
def test_mdsm_leaves_no_acne_under_the_corpus_spots(fair_runs, scene_name, res):
    """Issue 46 item 5: mdsm's acne under spot lights at most 0.3 % at its defaults, at every
    map size, though its window's leaks at 256 stay excepted above (measured: at most 0.19 %,
    real_beams_spot at 256). Catches the 3 x 3 kernel and window of before issue 46 (0.33 to
    1.24 % at 256 on all five: the kernel's reach, not the bias)."""
    acne = fair_runs[scene_name, res, "mdsm"][0]
    assert acne <= 0.3, f"acne {acne:.3f} %"


ZERO_BIAS = {
    "sm": {"bias": 0.0, "slope_bias": 0.0},
    "pcf": {"bias_min": 0.0, "bias_max": 0.0, "slope_bias": 0.0},
    "mdsm": {"bias": 0.0, "slope_bias": 0.0},
    "silhouette": {"bias": 0.0, "slope_bias": 0.0},
    "lispsm": {"bias": 0.0, "slope_bias": 0.0},
}


@pytest.mark.parametrize("technique", sorted(ZERO_BIAS))
def test_bias_forced_to_zero_shows_as_acne(scene_at, evaluate, technique):
    """On box_plane (a plane under an oblique light, a floating box) the defaults leave no
    acne, and with every bias term at 0 each technique shadows its lit surfaces: acne_pct (the
    run's own column) takes it, not only mae. Catches acne_pct not counting false shadow on lit
    surfaces, and a default bias of 0 (a term lost in the shared shader)."""
    scene = scene_at("box_plane", 128)
    default = evaluate(scene, technique, {"res": 1024}).row
    unbiased = evaluate(scene, technique, {"res": 1024, **ZERO_BIAS[technique]}).row
    assert default["acne_pct"] <= 0.1, default["acne_pct"]
    assert unbiased["acne_pct"] > 10.0, unbiased["acne_pct"]
    assert unbiased["leak_pct"] <= default["leak_pct"]  # less bias never leaks more light


def test_silhouette_keeps_the_box_front_face_lit(scene_at, evaluate):
    """Issue 14 item 13: at map 256 the silhouette map's corner depths lie up to a texel from
    the box's front face (a face tilted 79 degrees from the light), where a bias sized for the
    shadow map's own texel left 11 lit pixels shadowed (the shipped 512 x 512 view). With the
    receiver-plane term taken at each corner's own distance none are; sm shadows none either.
    Catches the corner tests biased for the texel centre instead of the corner."""
    scene = scene_at("box_plane", 512)
    for technique in ("sm", "silhouette"):
        e = evaluate(scene, technique, {"res": 256})
        position, normal = e.frame_arrays.position, e.frame_arrays.normal
        front = e.mask & (np.abs(normal[..., 1] + 1) < 1e-4) & (np.abs(position[..., 1] + 0.5) < 1e-3)
        lit = front & (e.reference.visibility == 1)
        assert lit.sum() > 4000  # the face is in view and lit
        assert np.count_nonzero(e.visibility[lit] < 1) == 0, technique


@pytest.mark.parametrize("scene_name", ["box_plane", "pins", "sphere_plane"])
@pytest.mark.parametrize("res_factor", [1.0, 2.0])
def test_pcf_edge_width_does_not_grow_with_k(scene_at, evaluate, scene_name, res_factor):
    """Issue 12 item 2: the region is the pixel's footprint (times res_factor), k only places
    samples inside it, so the soft pixels (0 < V < 1) change by less than 20 % from k = 4 to
    k = 36 (measured: at most 7 %). With the earlier region, sqrt(k) x res_factor texels, they
    grew about threefold. Catches a region that scales with k."""
    scene = scene_at(scene_name, 256)

    def soft(k):
        e = evaluate(scene, "pcf", {"k": k, "res_factor": res_factor})
        return np.count_nonzero((e.visibility > 0) & (e.visibility < 1) & e.mask)

    few, many = soft(4), soft(36)
    assert few > 100
    assert abs(many - few) < 0.2 * few, (few, many)


def test_no_acne_far_from_the_origin(evaluate):
    """hard_far_from_origin: box_plane moved 1e5 from the origin, where float32 positions and
    depths round to 0.008 units. Every map technique at its defaults stays free of acne there.
    Catches: a depth test without the float32 precision term (sm 0.28 %, lispsm 0.33 % acne)."""

    from harness import config
    from harness.scene import build_scene

    scene_file = ROOT / "experiments" / "hard_cases" / \
        "scenes.yaml"
    scene = build_scene("hard_far_from_origin",
                        config.load_scenes(scene_file)["hard_far_from_origin"], scene_file)
    for technique in ("sm", "pcf", "mdsm", "silhouette", "psm", "lispsm", "gmnpr"):
        row = evaluate(scene, technique).row
        assert row["acne_pct"] <= 0.1, (technique, row["acne_pct"])


# Family (c) at 10^5 triangles (issue 23 item 7) at map 1024, every technique's default: the
# shipped 512 x 512 view and a 256 x 256 one (a quarter of the pixels, each texel a quarter of
# the pixels too, so a bias failure stays as visible).
ARCHITECTURE_IMAGES = (256, 512)
# mdsm on the 512 view at its defaults since issue 46 (a 2 x 2 kernel over a 2 x 2 window):
# leak 0.143 % against sm's 0.009 %, still over the bar. With the 3 x 3 pair, as measured here
# before: leak 1.03 % against sm's 0.009 % (1176 pixels: 1061 on the grazing
# roofs, 93 on walls, 17 on the ground; 813 of them 3 pixels from the reference boundary, just
# outside the 2-pixel band, 232 at 4, 56 at 5; V mostly 1/18 to 3/18: one to three of the 18
# depth tests lit). Each is a shadowed point whose kernel reaches a cell whose window maximum
# (the 2-SM's extra depth, Pagot et al.'s choice) lies behind it, past the occluder's edge:
# the soft edge reaches the kernel plus the window radius into the shadow, and a texel of a
# roof grazing to the light spans several pixels. It is the window, not a bias: with the base
# depth biased for its own texel (no window reach) the leak stays 1.03 % and with slope_bias 0
# it is still 0.28 % (acne 34 %); it grows with the window (q 4, 9, 16, 25: 0.53, 1.03, 2.48,
# 3.18 %), vanishes without one (n 1: 0.061 %), and turns to acne with the minimum instead
# (extra min: acne 0.31 %, leak 0.18 %; n 3, both: 0.31 %, 1.03 %); pcf's footprint region
# as mdsm's kernel leaves 0.67 %. A faithful 2-SM at this view cannot meet the bar.
ARCHITECTURE_EXCEPTIONS = {(512, "mdsm"): WINDOW}


@pytest.fixture(scope="module")
def architecture_runs(gl_context, scene_at):
    """(image, technique) -> (acne_pct, leak_pct) at the defaults on architecture, and the same
    for pcf with slope_bias 0 (the control). One frame and one reference per view."""
    from harness.run import evaluate

    runs = {}
    for image in ARCHITECTURE_IMAGES:
        scene = scene_at("architecture", image)
        for technique, params in [("sm", {}), *((t, {}) for t in FILTERED),
                                  ("pcf, slope_bias 0", {"slope_bias": 0.0})]:
            row = evaluate(scene, technique.split(",")[0], params).row
            runs[image, technique] = (row["acne_pct"], row["leak_pct"])
    return runs


@pytest.mark.parametrize("technique", FILTERED)
@pytest.mark.parametrize("image", ARCHITECTURE_IMAGES)
def test_defaults_hold_on_dense_open_architecture(architecture_runs, image, technique):
    """Issue 23 item 7: on family (c) at 10^5 triangles (open, thin walls, roofs grazing to the
    light) pcf, mdsm and silhouette at their defaults show acne_pct <= 0.1 and leak_pct <= sm's
    + 0.1, except mdsm's window on the 512 view (ARCHITECTURE_EXCEPTIONS, which must keep
    failing), and the view does show acne without the slope term (pcf, slope_bias 0), so the
    bar tests it. Catches a default that loses the slope term, or a normal offset so large
    that light leaks past sm's (pcf with normal_offset 1 on the 512 view: leak 0.23 %)."""
    acne, leak = architecture_runs[image, technique]
    sm_leak = architecture_runs[image, "sm"][1]
    meets = acne <= 0.1 and leak <= sm_leak + 0.1
    if (image, technique) in ARCHITECTURE_EXCEPTIONS:
        assert not meets, f"now meets the bar (acne {acne:.3f}, leak {leak:.3f}): drop it"
    else:
        assert meets, (acne, leak, sm_leak)
    assert architecture_runs[image, "pcf, slope_bias 0"][0] > 1.0


NORMAL_OFFSET_BLOCK = ("    if (normal_offset > 0.0) {\n"
                       "        world = normal_offset_point(world, n, j);\n"
                       "        choose_face(world);\n"
                       "        j = map_jacobian(world);\n"
                       "    }\n")


def patch_shadow_map(monkeypatch, old: str, new: str):
    """Make every shader include a shadow_map.glsl with ``old`` (found once) replaced by
    ``new``."""
    from harness.gl import shaders

    resolve = shaders._resolve
    common = ROOT / "techniques" / "common"
    source = (common / "shadow_map.glsl").read_text()
    assert source.count(old) == 1
    copy = Path(tempfile.mkdtemp()) / "shadow_map.glsl"
    copy.write_text(source.replace(old, new))

    def patched(name, here):
        # the copy's own includes (cube_faces.glsl) still come from techniques/common/
        path = resolve(name, common if here == copy.parent else here)
        return copy if path.name == "shadow_map.glsl" else path

    monkeypatch.setattr(shaders, "_resolve", patched)


HARD_CASES = ROOT / "experiments" / "hard_cases" / "scenes.yaml"


def hard_case(name: str):
    from harness import config
    from harness.scene import build_scene

    return build_scene(name, config.load_scenes(HARD_CASES)[name], HARD_CASES)


@pytest.mark.parametrize("scene_name, technique", [
    *(("castle", t) for t in ("sm", *FILTERED, "csm", "lispsm")),
    ("hard_point_seam", "sm"), ("hard_point_seam", "pcf")])
def test_normal_offset_zero_is_the_shader_without_the_term(scene_at, evaluate, monkeypatch,
                                                           scene_name, technique):
    """normal_offset 0 gives V bit for bit equal to shadow_map.glsl without the term (the
    point not moved at all), on castle (walls, towers: every receiver orientation; csm's
    cascades, a warp) and on a point light's cube (hard_point_seam) at map 256, and so does
    the term's block run at 0 rather than skipped by its guard: the move is exactly 0, the
    face and the Jacobian re-taken at the same point are the same. Catches a lift not
    proportional to normal_offset (seen failing: (normal_offset + 0.01) x the texel, on 7 of
    these 8), or a 0 x inf (NaN) where the texel's world size degenerates. (Also checked once
    by hand against main's shadow_map.glsl before the term, 7504185: equal on all of these and
    on psm, gmnpr and hard_point_ring, with the guard and without.)"""
    scene = (scene_at(scene_name, 128) if scene_name == "castle"
             else hard_case(scene_name).with_resolution(128, 128))
    shipped = evaluate(scene, technique, {"res": 256, "normal_offset": 0.0}).visibility
    with monkeypatch.context() as patch:
        patch_shadow_map(patch, NORMAL_OFFSET_BLOCK, "")
        plain = evaluate(scene, technique, {"res": 256}).visibility
    with monkeypatch.context() as patch:  # the block run at 0 too, not skipped by its guard
        patch_shadow_map(patch, "if (normal_offset > 0.0) {", "if (true) {")
        unguarded = evaluate(scene, technique, {"res": 256, "normal_offset": 0.0}).visibility
    assert np.array_equal(shipped, plain)
    assert np.array_equal(unguarded, plain)
    offset = evaluate(scene, technique, {"res": 256, "normal_offset": 4.0}).visibility
    assert not np.array_equal(offset, plain)  # the block is the one that moves the point


def slab_visibility(points: np.ndarray, low, high, to_light) -> np.ndarray:
    """1 where the ray from each point toward the light misses the box [low, high], else 0
    (the slab test); ``to_light`` is (d, end): the ray is points + t d, 0 < t < end."""
    d, end = to_light
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (np.asarray(low) - points) / d, (np.asarray(high) - points) / d
    t_in = np.nanmax(np.minimum(t1, t2), axis=-1)
    t_out = np.nanmin(np.maximum(t1, t2), axis=-1)
    return np.where((t_in < t_out) & (t_out > 1e-4) & (t_in < end), 0.0, 1.0)


def lifted_mismatch(e, w, offset, low, high, light_position=None, direction=None):
    """Floor pixels (outside the predicted shadow's edge band) where V disagrees with the slab
    test of the floor points lifted by offset x w x sin(theta) along +z, w per pixel; and how
    many of them the predicted shadow holds."""
    from harness.truth import metrics

    position = e.frame_arrays.position.astype(np.float64)
    normal = e.frame_arrays.normal.astype(np.float64)
    floor = e.mask & (normal[..., 2] > 0.999) & (np.abs(position[..., 2]) < 1e-3)
    if light_position is not None:
        ray = np.asarray(light_position, float) - position
        to_light = (ray, 1.0)
    else:
        ray = -np.broadcast_to(np.asarray(direction, float), position.shape)
        to_light = (ray, np.inf)
    sin = np.sqrt(np.clip(1 - (ray[..., 2] / np.linalg.norm(ray, axis=-1)) ** 2, 0, 1))
    lifted = position + (offset * w * sin)[..., None] * np.array([0.0, 0.0, 1.0])
    if light_position is not None:
        to_light = (np.asarray(light_position, float) - lifted, 1.0)
    predicted = slab_visibility(lifted, low, high, to_light)
    compared = floor & ~metrics.edge_band(predicted, mask=floor)
    return (int((compared & (np.abs(e.visibility - predicted) > 0.5)).sum()),
            int((compared & (predicted == 0)).sum()))


@pytest.mark.parametrize("technique", ["sm", "pcf"])
def test_normal_offset_on_a_point_light_uses_the_face_texel_at_the_point(evaluate, technique):
    """A point light (hard_point_seam: a bar whose floor shadow crosses from the downward cube
    face into the sideways one): with normal_offset 32 at map 256 every floor pixel outside
    the edge band is the slab test of its point lifted by 32 x w x sin(theta), w = 2 d / res
    the face texel's side at d, the point's distance along its face's axis (measured: 0
    pixels differ). The lift is real (the unmoved prediction differs on 780-800 pixels) and
    the axis distance the right one (the straight-line distance differs on 12-15). Catches
    the texel size of the wrong distance, the offset off on the cube path, and (sm, seen
    failing: 45 pixels leak by the seam) the moved point kept in the face of the unmoved one,
    falling off its edge."""
    scene = hard_case("hard_point_seam").with_resolution(192, 192)
    light = np.asarray(scene.light.position, float)
    low = np.array([1.5, 0.45, 1.0]) - np.array([3.0, 0.3, 0.05]) / 2  # the bar
    high = low + np.array([3.0, 0.3, 0.05])
    res, offset = 256, 32.0
    e = evaluate(scene, technique, {"res": res, "normal_offset": offset})
    position = e.frame_arrays.position.astype(np.float64)
    axis_distance = np.abs(position - light).max(axis=-1)
    wrong, shadowed = lifted_mismatch(e, 2 * axis_distance / res, offset, low, high, light)
    assert shadowed > 300 and wrong <= 2, (wrong, shadowed)
    unmoved, _ = lifted_mismatch(e, 0 * axis_distance, offset, low, high, light)
    assert unmoved > 300


def test_normal_offset_in_cascades_uses_the_cascade_texel(evaluate, scene_at):
    """csm on box_plane at map 256 with normal_offset 64: every floor pixel outside the edge
    band is the slab test of its point lifted by 64 x w x sin(theta), w the texel side of the
    cascade that pixel used (column cascade_texel_<i>, map ``cascade``), at 4 and at 2 splits
    under fit frustum (cascade texels of 0.022 to 0.070 units: 435 and 368 shadowed pixels
    predicted; 0 differ; 208 and 271 differ from the unmoved points' test, and 11 at 4 splits
    with the last cascade's texel for every pixel). Before issue 46 the frustum fit split the
    camera's near and far (0.1, 100) as they were, texels of 0.078 and 0.163 in the shadow's
    cascade, and offset 32 told them apart; with the far plane clipped to the scene (and under
    sdsm, finer still) 32 texels lift the points too little (53 differ from unmoved at 4
    splits, 0 under sdsm). Catches the offset not reaching csm's shader or the texel of
    another cascade (the last one's)."""
    scene = scene_at("box_plane", 256)
    low, high = np.array([-0.5, -0.5, 1.0]), np.array([0.5, 0.5, 2.0])  # the box
    for splits in (4, 2):
        e = evaluate(scene, "csm", {"res": 256, "splits": splits, "normal_offset": 64.0,
                                    "fit": "frustum"})
        texel = np.array([e.row[f"cascade_texel_{i}"] for i in range(splits)])
        cascade = np.nan_to_num(e.arrays["map_cascade"]).astype(int)
        wrong, shadowed = lifted_mismatch(e, texel[cascade], 64.0, low, high,
                                          direction=scene.light.direction)
        assert shadowed > 250 and wrong <= 2, (splits, wrong, shadowed)
        unmoved, _ = lifted_mismatch(e, 0 * texel[cascade], 64.0, low, high,
                                     direction=scene.light.direction)
        assert unmoved > 100, (splits, unmoved)
    four = evaluate(scene, "csm", {"res": 256, "normal_offset": 64.0, "fit": "frustum"})
    last_texel = np.full(four.visibility.shape, four.row["cascade_texel_3"])
    last, _ = lifted_mismatch(four, last_texel, 64.0, low, high, direction=scene.light.direction)
    assert last > 2, last


def shadow_centroid(e) -> np.ndarray:
    """World xy centroid of the shadowed ground pixels (V < 0.5 on the plane z = 0)."""
    position, normal = e.frame_arrays.position, e.frame_arrays.normal
    ground = e.mask & (normal[..., 2] > 0.999) & (np.abs(position[..., 2]) < 1e-3)
    shadowed = ground & (e.visibility < 0.5)
    assert shadowed.sum() > 500
    return position[shadowed][:, :2].mean(axis=0)


def test_normal_offset_scales_with_the_texel_world_size(scene_at, evaluate):
    """On box_plane (a floating box over the plane z = 0, directional light d) sm's lookup
    point on the ground rises by normal_offset x w x sin(theta), w the map texel's world side
    (from the light frustum: 2 max(xmag, ymag) / res) and theta the light's angle from the
    normal; the shadow it sees is the ground shadow moved by that rise x |d_xy| / |d_z| toward
    the light. The measured shift of the shadow's centroid matches that within 10 % at maps
    256 and 512, so doubling res halves the world offset. Catches an offset in map texels
    rather than world units, the world size of the wrong axis, or a missing sine."""
    from harness.scene.transforms import fit_light

    scene = scene_at("box_plane", 256)
    d = np.asarray(scene.light.direction, float)
    d /= np.linalg.norm(d)
    sin_theta = np.linalg.norm(d[:2])
    offset = 32.0
    for res in (256, 512):
        proj = fit_light(scene, res).proj
        texel = 2.0 / min(proj[0, 0], proj[1, 1]) / res
        rise = offset * texel * sin_theta
        expected = -rise * d[:2] / abs(d[2])
        shift = (shadow_centroid(evaluate(scene, "sm", {"res": res, "normal_offset": offset}))
                 - shadow_centroid(evaluate(scene, "sm", {"res": res, "normal_offset": 0.0})))
        assert np.linalg.norm(shift - expected) < 0.1 * np.linalg.norm(expected), (res, shift,
                                                                                   expected)
