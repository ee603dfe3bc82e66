"""Moving geometry: object motion (spin, orbit, translate) in ``motion:``, its bad input, the
moved parts every technique draws or follows, and the reference traced from them per frame.
Small images (64 x 48), three frames."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from helpers import render_visibility

from harness import cli, config
from harness.truth import metrics
from harness.technique import registry
from harness.truth.reference import compute_reference
from harness.scene import build_scene
from harness.technique import Frame, NotApplicable, reset_gl_state

TECHNIQUES = list(registry.techniques())
# maps coarser than the 64 x 48 image, so that what each technique adds to its depth map (the
# silhouette map's edges, mdsm's depths) decides pixels
COARSE = {"sm": {"res": 32}, "silhouette": {"res": 32}, "mdsm": {"res": 32}, "pcf": {"res": 32}}

# box_plane's plane and a box named "caster", off centre so that an orbit moves it
STILL = {"resolution": [64, 48],
         "camera": {"position": [0, -6, 4], "target": [0, 0, 0], "up": [0, 0, 1]},
         "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
         "objects": [{"shape": "plane", "size": [10, 10]},
                     {"shape": "box", "name": "caster", "size": [1, 2, 0.5],
                      "translate": [1, 0, 1.5]}]}
# the caster spins a quarter turn and orbits 60 degrees about the vertical through the origin
MOVING = {**STILL, "motion": {"frames": 3, "objects": [
    {"object": "caster", "spin": 90, "orbit": 60, "centre": [0, 0, 0]}]}}
# the same under a spot light: silhouette's edge test uses each moved endpoint's direction
SPOT_LIT = {**MOVING, "light": {"type": "spot", "position": [-3, -4, 5], "target": [0, 0, 0],
                                "fov": 90}}


def scene(data, **objects_motion):
    """The scene ``data``; with keys, its ``motion`` of 3 frames moving object 1 by them."""
    if objects_motion:
        data = {**data, "motion": {"frames": 3, "objects": [{"object": 1, **objects_motion}]}}
    return build_scene("moving_box", config.Scene(**data))


def box_bounds(built, t):
    (part,) = [p for p in built.at_frame(t).parts if p.object_index == 1]
    return np.stack([part.vertices.min(0), part.vertices.max(0)]).astype(np.float64)


# --- the paths -----------------------------------------------------------------------------


def test_spin_orbit_and_translate_by_hand():
    """The box 1 x 2 x 0.5 at (1, 0, 1.5): a quarter spin about the vertical through its own
    centre swaps its x and y extents and leaves its centre; a half orbit about the vertical
    through the origin puts its centre at (-1, 0, 1.5), extents kept; translate (0, 2, 1)
    moves it by half that at the middle frame; spin about +x turns its y extent into z. The
    plane never moves (its arrays are the ones built). Catches a spin about the scene's centre
    or the world origin, an orbit about the box's own centre, the path spread over t / frames,
    an axis ignored, and a motion applied to every object."""
    cases = [({"spin": 90}, 2, (1, 0, 1.5), (2, 1, 0.5)),
             ({"orbit": 180, "centre": [0, 0, 0]}, 2, (-1, 0, 1.5), (1, 2, 0.5)),
             ({"translate": [0, 2, 1]}, 1, (1, 1, 2), (1, 2, 0.5)),
             ({"spin": 90, "spin_axis": [1, 0, 0]}, 2, (1, 0, 1.5), (1, 0.5, 2))]
    for motion_keys, t, centre, size in cases:
        built = scene(STILL, **motion_keys)
        bounds = box_bounds(built, t)
        np.testing.assert_allclose(bounds.mean(0), centre, atol=1e-6)
        np.testing.assert_allclose(bounds[1] - bounds[0], size, atol=1e-6)
        assert built.at_frame(t).parts[0].vertices is built.parts[0].vertices


def test_array_copies_spin_together_about_the_objects_centre():
    """Two copies 3 apart along x (centres x = 1 and 4): half a spin about the vertical through
    the object's centre (x = 2.5) swaps them, so the copy that started at x = 1 ends at 4.
    Catches each copy spun about its own centre (both would stay)."""
    data = {**STILL, "objects": [STILL["objects"][0], {
        **STILL["objects"][1], "array": {"count": [2, 1, 1], "step": [3, 0, 0]}}]}
    built = scene(data, spin=180)
    first, second = [p for p in built.at_frame(2).parts if p.object_index == 1]
    assert first.vertices.mean(0)[0] == pytest.approx(4, abs=1e-5)
    assert second.vertices.mean(0)[0] == pytest.approx(1, abs=1e-5)


def test_frame_zero_is_the_still_scene_and_moved_frames_have_their_own_keys():
    """Frame 0 of a scene whose objects move is the still scene bit for bit: the very parts'
    arrays and the still scene's key (its reference cache entry); frames where the caster
    moved have keys of their own, and naming an object changes no key. Catches frame 0 pushed
    through an identity transform (float rounding), and a key blind to the object motion (a
    moved frame would read frame 0's cached reference)."""
    still, moving = build_scene("s", config.Scene(**STILL)), scene(MOVING)
    zero = moving.at_frame(0)
    assert zero.key == still.key
    for a, b in zip(zero.parts, still.parts):
        assert np.array_equal(a.vertices, b.vertices) and a.vertices.dtype == np.float32
    assert zero.poses is None
    keys = {moving.at_frame(t).key for t in range(3)}
    assert len(keys) == 3
    unnamed = {**STILL, "objects": [STILL["objects"][0],
                                    {k: v for k, v in STILL["objects"][1].items() if k != "name"}]}
    assert build_scene("s", config.Scene(**unnamed)).key == still.key


# --- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize("change, key, says", [
    ({"motion": {"frames": 3, "objects": [{"object": 5, "spin": 30}]}},
     "motion.objects.0.object", "no object 5"),
    ({"motion": {"frames": 3, "objects": [{"object": "tower", "spin": 30}]}},
     "motion.objects.0.object", "no object named 'tower'"),
    ({"motion": {"frames": 3, "objects": [{"object": 1, "spin": ".nan"}]}},
     "motion.objects.0.spin", "finite number"),
    ({"motion": {"frames": 3, "objects": [{"object": 1, "spin": 3601}]}},
     "motion.objects.0.spin", "less than or equal to 3600"),
    ({"motion": {"frames": 3, "objects": [{"object": 1, "orbit": -4000}]}},
     "motion.objects.0.orbit", "greater than or equal to -3600"),
    ({"motion": {"frames": 3, "objects": [{"object": 1, "spin": 9, "spin_axis": [0, 0, 0]}]}},
     "motion.objects.0.spin_axis", "zero vector"),
    ({"motion": {"frames": 3, "objects": [{"object": 1, "spin": 9},
                                          {"object": "caster", "orbit": 9}]}},
     "motion.objects.1.object", "moves along another path too"),
    ({"objects": [{"shape": "plane", "name": "caster"}, STILL["objects"][1]]},
     "objects.1.name", "'caster' names object 0 too"),
])
def test_bad_object_motion_is_exit_2_one_line_naming_file_and_key(change, key, says, tmp_path,
                                                                  capsys):
    """An object motion naming a missing index or name, a NaN or absurd (over 3600 degrees)
    spin or orbit, a zero axis, one object on two paths, two objects of one name: exit 2, one
    line naming the file, the scene and the key path, nothing written. Catches a missing
    object found only when the frame is built (a traceback, or a run half written), NaN let
    through to the bounds check, and the check's message pinned to the scene, not its key."""
    text = yaml.safe_dump({"scenes": {"moving": {**STILL, **change}}}).replace("'.nan'", ".nan")
    path = tmp_path / "scenes.yaml"
    path.write_text(text)
    out = tmp_path / "out"
    code = cli.main(["run", "--scene-file", str(path), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"{path}:" in err and f"scenes.moving.{key}:" in err and says in err, err
    assert not out.exists()


# --- techniques follow the moving casters ----------------------------------------------------


def sequence_and_still(name, k, settings=None, data=MOVING):
    """V of ``name`` at frame ``k`` of ``data``, reached by preparing at frame 0 and moving
    frame by frame, V of a fresh run on the still scene of frame k, V at frame 0 and both
    frames, each run with ``settings``; None where the technique does not apply. And the
    resources, for the caller to release."""
    cls = registry.get(name)
    moving = scene(data)
    frame, still = Frame(moving), Frame(moving.at_frame(k))
    params = cls.Params(**(settings or {}))
    moved, fresh = cls(params), cls(params)
    resources = (moved, fresh, frame, still)
    try:
        moved.prepare(frame)
        moved.update(frame)
    except NotApplicable:
        return None, resources
    first = render_visibility(moved, frame)
    for t in range(1, k + 1):
        frame.move_to(t)
        moved.update(frame)
        followed = render_visibility(moved, frame)
    fresh.prepare(still)
    fresh.update(still)
    return (followed, render_visibility(fresh, still), first, frame, still), resources


@pytest.mark.parametrize("name", TECHNIQUES)
@pytest.mark.parametrize("data", [MOVING, SPOT_LIT], ids=["directional", "spot"])
def test_a_moved_caster_renders_what_a_still_scene_with_it_there_does(name, data, gl_context):
    """Frame 2 of MOVING and SPOT_LIT (the box spun and orbited), reached by preparing at
    frame 0 and updating at each frame, gives exactly the V of a fresh run on the still scene
    with the box at frame 2's place, and that V differs from frame 0's (the shadow moved).
    Catches a Frame.move_to that leaves the vertex buffer (every map and the G-buffer) at
    frame 0, a light frustum or warp body fitted to frame 0's bounds, geometry built in
    prepare that ignores the parts' poses (silhouette's edge mesh, or its face normals left
    unturned; sv's GPU volumes, uploaded once and drawn with an identity model), and poses
    applied again to a moved frame run as a still scene (whose parts are already moved)."""
    result, resources = sequence_and_still(name, 2, COARSE.get(name), data)
    try:
        if result is None:
            pytest.skip(f"{name} does not apply to this light")
        followed, still_v, first, frame, still = result
        assert np.array_equal(frame.arrays.position, still.arrays.position)
        np.testing.assert_array_equal(followed, still_v)
        assert np.count_nonzero(followed != first) > 20
    finally:
        for resource in resources:
            resource.release()
        reset_gl_state()


@pytest.fixture(scope="module")
def references():
    moving = scene(MOVING)
    return [compute_reference(moving.at_frame(t), samples=4) for t in (0, 2)]


@pytest.mark.parametrize("name", ["sm", "silhouette"])
def test_a_moved_frame_matches_its_own_reference(name, references, gl_context):
    """The reference is traced per frame from the moved triangles: frame 2's differs from
    frame 0's where the box's shadow moved (over 30 pixels), and sm's and silhouette's V at
    frame 2 is close to frame 2's reference (mean error under 0.02), far closer than to frame
    0's. Catches a reference built from the parts as written (or read from frame 0's cache
    entry), which would leave frame 2's V far from its reference."""
    zero, two = references
    assert np.count_nonzero(np.abs(zero.visibility - two.visibility) > 0.5) > 30
    result, resources = sequence_and_still(name, 2)
    try:
        followed, _, _, frame, _ = result
        mask = frame.compared_pixels(two.covered)
        error = metrics.mae(followed, two.visibility, mask=mask)
        assert error < 0.02
        assert metrics.mae(followed, zero.visibility, mask=mask) > 3 * error
    finally:
        for resource in resources:
            resource.release()
        reset_gl_state()
