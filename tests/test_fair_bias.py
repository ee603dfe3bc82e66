"""Fair bias (issue 12, items 1-3; issue 14, item 13): every map technique's depth bias follows
its own sampling footprint (receiver-plane bias, techniques/shadow_map.glsl), PCF's region is
the pixel's footprint, and acne and leaks are measured apart (harness.metrics)."""

from __future__ import annotations

import numpy as np
import pytest

from harness import metrics

SHIPPED = ("sphere_plane", "box_plane", "pins", "castle", "crowd", "terrain_long", "slant_edge",
           "silhouette_hard", "camera_in_shadow", "jeep")
MAPS = (256, 1024, 4096)
FILTERED = ("pcf", "mdsm", "silhouette")

# The runs that miss the issue's bar at the defaults, and why. No other default serves them
# without breaking others (measured): slope_bias 0.5 puts pcf's acne above 1 % at map 1024 on
# box_plane, castle, crowd, jeep and camera_in_shadow and leaves MDSM's leaks as they are;
# slope_bias 4 leaves the acne of these runs above 0.1 % except on jeep and terrain_long,
# whose leaks stay.
RESOLUTION = ("a texel covers 2-5 pixels of this view: pcf's smallest region (one texel, "
              "Reeves et al.'s MinSize) and the map's own jaggies reach past the 2-pixel edge "
              "band (sm's half texel already reaches 0.15 % on camera_in_shadow)")
WINDOW = ("MDSM's extra depths come from the q-texel window, so its soft edge reaches the "
          "window radius plus the kernel (about 2.5 texels) beyond the shadow boundary, past "
          "the 2-pixel band where a texel covers a pixel or more: Pagot et al.'s semantics, "
          "as wide with slope_bias 0")
TERRAIN = ("terrain_long puts an 840-unit plane in one map: texels of 17-270 pixels near the "
           "camera and sub-texel boxes; sm misses the bar too (acne 1.2 % at map 1024), this "
           "is the warps' scene")
EXCEPTIONS = {
    **{("terrain_long", res, t): TERRAIN for res in MAPS for t in FILTERED},
    **{(s, 256, "pcf"): RESOLUTION
       for s in ("camera_in_shadow", "castle", "crowd", "jeep", "pins", "silhouette_hard")},
    **{(s, 256, "mdsm"): WINDOW for s in SHIPPED},
    **{(s, 1024, "mdsm"): WINDOW for s in ("camera_in_shadow", "castle", "crowd", "pins")},
}
del EXCEPTIONS["terrain_long", 4096, "silhouette"]  # meets the bar


@pytest.fixture(scope="module")
def fair_runs(gl_context, scene_at):
    """(scene, map, technique) -> (acne_pct, leak_pct) at the defaults, shipped 512 x 512 views;
    one frame and one reference per scene. About 40 s on 2 busy cores: the map passes and
    shader builds cost more than the pixels, so the shipped size costs no more than 256."""
    from harness import registry
    from harness.reference import compute_reference
    from harness.technique import Frame, reset_gl_state

    runs = {}
    for name in SHIPPED:
        scene = scene_at(name, 512)
        reference = compute_reference(scene, samples=16)
        frame = Frame(scene)
        mask = frame.compared_pixels(reference.covered)
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
                    runs[name, res, technique] = (
                        metrics.acne_pct(v, reference.visibility, mask=mask),
                        metrics.leak_pct(v, reference.visibility, mask=mask))
        finally:
            frame.release()
    return runs


@pytest.mark.parametrize("technique", FILTERED)
@pytest.mark.parametrize("res", MAPS)
@pytest.mark.parametrize("scene_name", SHIPPED)
def test_defaults_leave_no_acne_and_no_leak_beyond_sm(fair_runs, scene_name, res, technique):
    """Issue 12: at its defaults a technique shows acne_pct <= 0.1 and leak_pct <= sm's + 0.1
    on every shipped scene and map size. EXCEPTIONS lists where that cannot hold and why; an
    exception that starts meeting the bar fails here too, so the list stays true. Catches a
    slope term lost or too small (pcf at 1024 on castle, crowd, jeep: acne; silhouette on the
    box face), or too large (leaks beyond sm's)."""
    acne, leak = fair_runs[scene_name, res, technique]
    sm_leak = fair_runs[scene_name, res, "sm"][1]
    meets = acne <= 0.1 and leak <= sm_leak + 0.1
    reason = EXCEPTIONS.get((scene_name, res, technique))
    if reason is None:
        assert meets, f"acne {acne:.3f} %, leak {leak:.3f} % (sm {sm_leak:.3f} %)"
    else:
        assert not meets, f"now meets the bar (acne {acne:.3f}, leak {leak:.3f}): drop the exception"


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
    from pathlib import Path

    from harness import config
    from harness.scene import build_scene

    scene_file = Path(__file__).resolve().parent.parent / "experiments" / "hard_cases" / \
        "scenes.yaml"
    scene = build_scene("hard_far_from_origin",
                        config.load_scenes(scene_file)["hard_far_from_origin"], scene_file)
    for technique in ("sm", "pcf", "mdsm", "silhouette", "psm", "lispsm", "gmnpr"):
        row = evaluate(scene, technique).row
        assert row["acne_pct"] <= 0.1, (technique, row["acne_pct"])
