"""Moving scenes: camera and light paths, frames moved without rebuilding, per-frame truth,
flicker, the worst frame, and runs that resume. Small images (64 to 128 pixels), few frames."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
import yaml

from harness import cli, config
from harness.truth import metrics
from harness.scene import motion
from harness.technique import registry
from harness.run import evaluate
from harness.scene import build_scene
from harness.technique import Frame, NotApplicable, reset_gl_state
from helpers import moving, render_visibility

TECHNIQUES = list(registry.techniques())


# --- the paths -----------------------------------------------------------------------------


def test_camera_orbit_and_dolly_by_hand():
    """box_plane's camera (0, -6, 4) looking at the origin, up +z: a quarter orbit puts it at
    (6, 0, 4) (counter-clockwise seen from above), and a dolly of 0.5 on top halves its
    distance, (3, 0, 2) at the last frame; half way, 45 degrees and three quarters of the
    distance. Catches the orbit about another axis or through the world origin instead of the
    target, and frames spread over t / frames (the last frame short of the path's end)."""
    camera = config.Camera(position=(0, -6, 4), target=(0, 0, 0), up=(0, 0, 1))
    path = config.Motion(frames=3, camera_orbit=90, camera_dolly=0.5)
    assert motion.camera_at(camera, path, 2).position == pytest.approx((3, 0, 2), abs=1e-12)
    half = 0.75 * 6 / math.sqrt(2)
    assert motion.camera_at(camera, path, 1).position == pytest.approx((half, -half, 3),
                                                                       abs=1e-12)
    shifted = config.Camera(position=(1, -5, 4), target=(1, 1, 0), up=(0, 0, 1))
    assert motion.camera_at(shifted, config.Motion(frames=2, camera_orbit=180), 1).position \
        == pytest.approx((1, 7, 4), abs=1e-12)


def test_light_orbit_turns_a_direction_and_a_spot_about_the_scene_centre(shipped_scenes):
    """A directional light (1, 0, -1) turned 90 degrees about +z travels along (0, 1, -1);
    sphere_plane's spot light turns, position and target together, about the vertical axis
    through the centre of the scene's bounds, so its distance to that axis, its height and its
    aim distance stay. Catches a spot turned about the world origin, or its target left."""
    light = config.DirectionalLight(type="directional", direction=(1, 0, -1))
    turned = motion.light_at(light, config.Motion(frames=2, light_orbit=90), (0, 0, 1), None, 1)
    assert turned.direction == pytest.approx((0, 1, -1), abs=1e-12)
    scene = moving(shipped_scenes, "sphere_plane", (32, 32), frames=4, light_orbit=120)
    centre = scene.bounds.mean(axis=0)
    first = scene.at_frame(0).config.light
    for t in (1, 3):
        spot = scene.at_frame(t).config.light
        for before, after in ((first.position, spot.position), (first.target, spot.target)):
            radius = [np.hypot(*(np.subtract(p, centre)[:2])) for p in (before, after)]
            assert radius[1] == pytest.approx(radius[0], rel=1e-12)
            assert after[2] == pytest.approx(before[2], abs=1e-12)
        angle = [math.atan2(*(np.subtract(p, centre)[1::-1])) for p in (first.position,
                                                                      spot.position)]
        assert math.degrees(angle[1] - angle[0]) % 360 == pytest.approx(40 * t, abs=1e-9)
        aim = np.subtract(spot.target, spot.position)
        assert np.linalg.norm(aim) == pytest.approx(
            np.linalg.norm(np.subtract(first.target, first.position)), rel=1e-12)


def test_frame_zero_is_the_still_scene_and_every_frame_has_its_own_key(shipped_scenes):
    """Frame 0 of a moving scene is the scene as written, bit for bit: the same key as the
    still scene (its reference cache entry and run ids are shared); every other frame has a
    key of its own, and a scene that moves has another key than the still one. Catches
    frame 0 rebuilt through the rotation (rounding changes the key) and a key that ignores
    the motion or the frame."""
    still = moving(shipped_scenes, "box_plane", (32, 32))
    scene = moving(shipped_scenes, "box_plane", (32, 32), frames=4, camera_orbit=30,
                   light_orbit=-20)
    assert scene.frames == 4 and still.frames == 1
    assert scene.at_frame(0).key == still.key and scene.at_frame(0).config == still.config
    keys = {scene.at_frame(t).key for t in range(4)}
    assert len(keys) == 4 and scene.key not in keys
    with pytest.raises(IndexError):
        scene.at_frame(4)


# --- bad input -------------------------------------------------------------------------------

GOOD = {"resolution": [32, 32],
        "camera": {"position": [0, -6, 4], "target": [0, 0, 0], "up": [0, 0, 1]},
        "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
        "objects": [{"shape": "plane"}, {"shape": "box", "translate": [0, 0, 1]}]}


@pytest.mark.parametrize("motion_value, key, says", [
    ({"frames": 1}, "motion.frames", "greater than or equal to 2"),
    ({"frames": 1001}, "motion.frames", "less than or equal to 1000"),
    ({"frames": 3, "camera_orbit": ".nan"}, "motion.camera_orbit", "finite number"),
    ({"frames": 3, "light_orbit": ".inf"}, "motion.light_orbit", "finite number"),
    ({"frames": 3, "camera_dolly": "-.inf"}, "motion.camera_dolly", "finite number"),
    ({"frames": 3, "light_orbit": 3601}, "motion.light_orbit", "less than or equal to 3600"),
    ({"frames": 3, "camera_orbit": -4000}, "motion.camera_orbit", "greater than or equal"),
    ({"frames": 3, "camera_dolly": 1.0}, "motion.camera_dolly", "passes through the camera's"),
    ({"frames": 3, "camera_dolly": 1.5}, "motion.camera_dolly", "passes through the camera's"),
    ({"frames": 3, "camera_dolly": -11}, "motion.camera_dolly", "greater than or equal to -10"),
    ({"camera_orbit": 30}, "motion.frames", "required key is missing"),
    ({"frames": 3, "spin": 30}, "motion.spin", "unknown key"),
])
def test_bad_motion_is_exit_2_one_line_naming_file_scene_and_key(motion_value, key, says,
                                                                  tmp_path, capsys):
    """frames outside 2..1000, NaN, Inf, angles above 3600 degrees, a dolly reaching or passing
    the target (1 or more) or backing away absurdly, a missing or unknown key: exit 2, one line
    naming the file, the scene and the key path and saying what is wrong, nothing written.
    Catches a dolly of exactly 1 accepted (the camera on its target), and NaN or Inf let
    through to the bounds (which then report "less than or equal", not "finite")."""
    text = yaml.safe_dump({"scenes": {"orbiting": {**GOOD, "motion": motion_value}}})
    path = tmp_path / "scenes.yaml"
    for special in (".nan", "-.inf", ".inf"):
        text = text.replace(f"'{special}'", special)
    path.write_text(text)
    out = tmp_path / "out"
    code = cli.main(["run", "--scene-file", str(path), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(path) in err and f"scenes.orbiting.{key}" in err and says in err, err
    assert not out.exists()


# --- frames moved, techniques updated --------------------------------------------------------


@pytest.mark.parametrize("name", TECHNIQUES)
def test_a_moved_frame_renders_what_a_still_frame_at_its_camera_and_light_does(
        name, shipped_scenes, gl_context):
    """Frame 2 of a moving box_plane and sphere_plane (camera and light orbiting, dolly),
    reached by moving one frame and updating one technique, gives exactly the V of a fresh
    frame and technique built on the still scene of frame 2, and moving back gives frame 0's
    V again. Catches an update that misses what depends on the light or the camera (sv keeping
    frame 0's volumes, a map fitted once in prepare, the warps' frustum), and a Frame.move_to
    that leaves the G-buffer or the camera matrices behind."""
    cls = registry.get(name)
    for scene_name in ("box_plane", "sphere_plane"):
        scene = moving(shipped_scenes, scene_name, (48, 32), frames=3, camera_orbit=40,
                       light_orbit=50, camera_dolly=0.3)
        frame, still = Frame(scene), Frame(scene.at_frame(2))
        moved, fresh = cls(cls.Params()), cls(cls.Params())
        try:
            try:
                moved.prepare(frame)
                moved.update(frame)
            except NotApplicable:
                continue
            first = render_visibility(moved, frame)
            frame.move_to(1)
            moved.update(frame)
            render_visibility(moved, frame)
            frame.move_to(2)
            moved.update(frame)
            fresh.prepare(still)
            fresh.update(still)
            np.testing.assert_array_equal(render_visibility(moved, frame), render_visibility(fresh, still))
            assert np.array_equal(frame.arrays.position, still.arrays.position)
            frame.move_to(0)
            moved.update(frame)
            np.testing.assert_array_equal(render_visibility(moved, frame), first)
        finally:
            for resource in (moved, fresh, frame, still):
                resource.release()
            reset_gl_state()


# --- flicker ---------------------------------------------------------------------------------


def test_flicker_by_hand():
    """Two 2x3 frames. Pixel by pixel, (V - V_prev) - (R - R_prev): a steady error (0), a
    change the truth makes too (0), an edge that jumps the wrong way (|1 - 0| = 1), a pop
    against a still truth (|-0.5|), a pixel compared in one frame only (left out), and one
    compared in neither: mean of 0, 0, 1, 0.5 = 0.375. Catches the change of V alone (no
    reference change subtracted: 0.5 + 1 + 1 + 0.5 over 4), a mean over only the current
    frame's mask, and an absolute difference per frame (|V - R| now minus before)."""
    v_prev = np.array([[0.2, 1.0, 0.0], [1.0, 0.3, 0.9]])
    v = np.array([[0.2, 0.0, 1.0], [0.5, 0.9, 0.0]])
    r_prev = np.array([[0.0, 1.0, 0.0], [1.0, 0.1, 0.1]])
    r = np.array([[0.0, 0.0, 0.0], [1.0, 0.2, 0.7]])
    mask_prev = np.array([[True, True, True], [True, False, False]])
    mask = np.array([[True, True, True], [True, True, False]])
    assert metrics.flicker(v, v_prev, r, r_prev, mask=mask, mask_previous=mask_prev) \
        == pytest.approx(0.375)
    assert metrics.flicker(v_prev, v_prev, r_prev, r_prev) == 0.0
    assert math.isnan(metrics.flicker(v, v_prev, r, r_prev, mask=~mask_prev,
                                      mask_previous=mask_prev))
    with pytest.raises(ValueError, match="shape"):
        metrics.flicker(v, v_prev[:, :2], r, r_prev)
    with pytest.raises(ValueError, match="mask"):
        metrics.flicker(v, v_prev, r, r_prev, mask=mask.astype(int))


def test_pop_frames_by_hand():
    """Median of (1, 1, 2, 1, 11) is 1: only 11 exceeds five times it; a NaN frame (nothing
    compared in both) is left out of the median and the count; a series at 0 has no pop until
    a frame changes. Catches the mean in place of the median (3.2: no pop) and NaN counted."""
    assert metrics.pop_frames([1, 1, 2, 1, 11]) == 1
    assert metrics.pop_frames([1, np.nan, 1, 6]) == 1
    assert metrics.pop_frames([1, 1, 5]) == 0
    assert metrics.pop_frames([0.0, 0.0, 0.0]) == 0
    assert metrics.pop_frames([np.nan]) == 0
    with pytest.raises(ValueError):
        metrics.pop_frames(np.zeros((2, 2)))


# --- runs on moving scenes -------------------------------------------------------------------


@pytest.mark.parametrize("name", TECHNIQUES)
def test_a_still_scene_given_five_frames_does_not_flicker(name, shipped_scenes, gl_context):
    """box_plane with motion {frames: 5} and nothing moving: every technique (all are
    deterministic: pcf's jitter is seeded) has flicker exactly 0, no pop, the still run's mae
    as its mean and worst frame, and 5 frame times. Catches a run that compares a frame's V
    with the previous frame's reference (flicker = mae), and a technique whose update does not
    leave it as it was (sv appending volumes, a map refitted wrongly)."""
    still = evaluate(moving(shipped_scenes, "box_plane", (64, 48)), name)
    sequence = evaluate(moving(shipped_scenes, "box_plane", (64, 48), frames=5), name)
    if still.row["status"] == "skipped":
        pytest.skip(still.row["error"])
    row = sequence.row
    assert row["status"] == "ok", row.get("error")
    assert row["flicker"] == 0.0 and row["flicker_max"] == 0.0 and row["pop_frames"] == 0
    assert row["mae"] == still.row["mae"] and row["mae_max"] == still.row["mae"]
    assert row["frames"] == 5 and len(row["frame_ms"]) == 5
    np.testing.assert_array_equal(sequence.visibility, still.visibility)
    assert list(sequence.arrays["series_flicker"][1:]) == [0.0] * 4


class Shimmering(registry.get("sm")):
    """sm with a seeded noise of +-0.2 added to V, drawn anew each frame (a test double).

    ==============  =====================  =======  =====
    Parameter       Meaning                Default  Range
    ==============  =====================  =======  =====
    ``res``         as sm                  1024
    ``bias``        as sm                  0.02
    ``slope_bias``  as sm                  1.0
    ==============  =====================  =======  =====
    """

    name = "shimmering"

    def prepare(self, frame):
        super().prepare(frame)
        self.frames_drawn = 0

    def render(self, frame):
        output = super().render(frame)
        noise = np.random.default_rng(self.frames_drawn).uniform(-0.2, 0.2,
                                                                 output.visibility.shape)
        self.frames_drawn += 1
        output.visibility = np.clip(output.visibility + noise, 0, 1).astype(np.float32)
        return output


def test_per_frame_noise_flickers_while_its_mean_error_is_the_still_runs(
        shipped_scenes, gl_context, monkeypatch):
    """A technique adding fresh noise each frame (uniform +-0.2, clipped to [0, 1]) on a
    still scene given 6 frames. Where V is 0 or 1 (all but a few edge pixels) a frame's noise
    is 0 half the time and U(0, 0.2) otherwise, so two frames differ by 0.5 x 0.1 + 0.25 x
    0.2 / 3 = 1/15 on average: flicker is 1/15 to 10%, while the mean mae over the frames is the
    still run's (0.054, one draw) to 6%, as is every frame's (each frame's noise has one
    distribution; a frame's mae spreads by about 2% over its ~2600 compared pixels). Catches
    flicker computed from the reference's change alone (0 here), and the sequence's mae summed
    or taken from one frame instead of averaged."""
    found = {**registry.techniques(), "shimmering": Shimmering}
    monkeypatch.setattr(registry, "techniques", lambda: found)
    still = evaluate(moving(shipped_scenes, "box_plane", (64, 48)), "shimmering")
    sequence = evaluate(moving(shipped_scenes, "box_plane", (64, 48), frames=6), "shimmering")
    row = sequence.row
    assert row["flicker"] == pytest.approx(1 / 15, rel=0.1)
    assert row["flicker_max"] >= row["flicker"]
    assert row["mae"] == pytest.approx(still.row["mae"], rel=0.06)
    np.testing.assert_allclose(sequence.arrays["series_mae"], still.row["mae"], rtol=0.06)


def test_shadow_volumes_flicker_less_than_a_coarse_shadow_map_on_an_orbiting_light(
        shipped_scenes, gl_context):
    """castle at 128x128, the light turning 30 degrees over 6 frames: sv (exact up to the
    pixel's point sample) flickers at most 0.8 times sm with a 256 map, whose texels crawl
    along the moving edges (measured 0.0129 against 0.0191). Catches sv keeping frame 0's
    volumes (its shadows then stand still while the truth moves) and flicker without the
    reference's change subtracted (both then measure the shadows' own motion)."""
    scene = moving(shipped_scenes, "castle", (128, 128), frames=6, light_orbit=30)
    sm = evaluate(scene, "sm", {"res": 256}).row
    sv = evaluate(scene, "sv").row
    assert sv["flicker"] < 0.8 * sm["flicker"], (sv["flicker"], sm["flicker"])
    assert sv["mae"] < sm["mae"]


def test_the_warps_do_not_pop_where_theta_crosses_zero(shipped_scenes, gl_context):
    """castle at 128x128 with the light along the view direction at frame 4 of 9, turning
    from 8 degrees one side of it to 8 degrees the other (theta 7.4, 5.5, 3.7, 1.8, 0, 1.8
    ...): psm, lispsm and gmnpr at a 256 map run every frame with finite matrices and no
    frame flickers more than five times the sequence's median. Catches a warp that breaks
    at theta = 0 (lambda unclamped: lispsm's matrices NaN there, gmnpr divides by zero).
    Measured, not asserted: the pre-fix helper axis (the map turned at theta = 0 exactly) pops
    no more than the fixed one here; psm falls back to the unwarped map on every frame."""
    scene_config = shipped_scenes["castle"].model_dump(mode="json")
    view = np.subtract(scene_config["camera"]["target"], scene_config["camera"]["position"])
    before = motion.rotation((0, 0, 1), -8) @ (view / np.linalg.norm(view))
    scene_config.update(resolution=[128, 128], motion={"frames": 9, "light_orbit": 16},
                        light={"type": "directional", "direction": before.tolist()})
    scene = build_scene("castle", config.Scene(**scene_config))
    for name in ("psm", "lispsm", "gmnpr"):
        run = evaluate(scene, name, {"res": 256})
        row, theta = run.row, run.arrays["series_extra_theta_deg"]
        assert row["status"] == "ok", row.get("error")
        assert theta[4] < 1e-3 and theta[0] > 7 and theta[8] > 7
        assert row["nonfinite"] == 0
        assert row["pop_frames"] == 0, (name, run.arrays["series_flicker"])


def test_the_worst_frame_and_the_strip_around_it(shipped_scenes, gl_context):
    """A camera orbit of 8 frames with sm at a 64 map: the stored worst frame is the frame of
    the largest flicker, its V, reference and error (|V - V_ref| on the compared pixels, NaN
    elsewhere) are that frame's, and the strip holds the frames within two of it, each V with
    its own reference; frame 0's V and coverage are the run's visibility and covered. Catches
    a worst frame or strip taken one frame late, and an error image of another frame."""
    scene = moving(shipped_scenes, "box_plane", (64, 48), frames=8, camera_orbit=40)
    run = evaluate(scene, "sm", {"res": 64})
    a, row = run.arrays, run.row
    flicker = a["series_flicker"]
    worst = int(np.nanargmax(flicker))
    assert int(a["worst_frame"]) == worst == row["worst_frame"]
    assert row["flicker_max"] == flicker[worst] and row["mae_max"] == a["series_mae"].max()
    frames = list(range(max(worst - 2, 0), min(worst + 3, 8)))
    assert list(a["strip_frames"]) == frames
    worst_strip = frames.index(worst)
    np.testing.assert_array_equal(a["strip_visibility"][worst_strip], a["worst_visibility"])
    np.testing.assert_array_equal(a["strip_reference"][worst_strip], a["worst_reference"])
    error = a["worst_error"]
    compared = ~np.isnan(error)
    np.testing.assert_allclose(error[compared], np.abs(a["worst_visibility"]
                                                       - a["worst_reference"])[compared])
    assert np.nanmean(error) == pytest.approx(a["series_mae"][worst], rel=1e-5)
    from harness.truth.reference import compute_reference

    for k, t in enumerate(frames):
        reference = compute_reference(scene.at_frame(t))
        np.testing.assert_array_equal(a["strip_reference"][k], reference.visibility)
    np.testing.assert_array_equal(a["visibility"], run.visibility)
    assert np.array_equal(a["covered"], run.frame_arrays.covered)


def result_rows(out):
    with (out / "results.csv").open() as f:
        return list(csv.DictReader(f))


def _with_box_orbit(small_scene_file, **orbit):
    """A 64 x 48 scene file with box_plane and box_orbit, box_plane moving 4 frames by
    ``orbit``."""
    path = small_scene_file("box_plane", size=(64, 48))
    scenes = yaml.safe_load(path.read_text())
    scenes["scenes"]["box_orbit"] = {**scenes["scenes"]["box_plane"],
                                     "motion": {"frames": 4, **orbit}}
    path.write_text(yaml.safe_dump(scenes))
    return path


def test_moving_runs_resume_like_still_ones(small_scene_file, tmp_path, gl_context, capsys):
    """A scene file with a moving and a still scene: the run records flicker, its worst
    frame and pops for the moving one only (the still one's columns empty), the arrays hold
    the per-frame series; after one row is lost (a kill), the same command renders that run
    alone, with the same run id and the same values. Catches a moving run whose id changes
    between invocations and a moving row written without its status."""
    path = _with_box_orbit(small_scene_file, camera_orbit=20)
    out = tmp_path / "run"
    args = ["run", "--scene-file", str(path), "--techniques", "sm,sv", "--out", str(out),
            "--quiet"]
    assert cli.main(args) == 0
    rows = {(r["scene"], r["technique"]): r for r in result_rows(out)}
    orbit = rows[("box_orbit", "sm")]
    assert orbit["frames"] == "4" and float(orbit["flicker"]) > 0 and orbit["pop_frames"] != ""
    assert orbit["worst_frame"] != "" and rows[("box_plane", "sm")]["flicker"] == ""
    with np.load(out / orbit["array"]) as z:
        assert z["series_mae"].shape == (4,) and z["series_frame_ms"].shape == (4,)
    kept = [r for r in result_rows(out) if r["run_id"] != orbit["run_id"]]
    from harness import results

    results.write_rows(out, kept)
    capsys.readouterr()
    assert cli.main(args) == 0
    assert "1 rendered now, 3 already done" in capsys.readouterr().out
    again = {(r["scene"], r["technique"]): r for r in result_rows(out)}[("box_orbit", "sm")]
    assert again["run_id"] == orbit["run_id"]
    for column in ("mae", "mae_max", "flicker", "flicker_max", "pop_frames", "worst_frame"):
        assert again[column] == orbit[column], column


def test_the_dashboard_shows_error_and_flicker_per_frame_and_the_worst_frames(
        small_scene_file, tmp_path, gl_context):
    """A moving and a still box_plane, sm at two map sizes and sv: the moving scene's view has
    a chart of mae, edge_mae and flicker against frame with one line per run (4 frames; flicker
    from frame 1), each run's worst frame beside its reference with its strip, and flicker in
    each run's plot values (the point size of the cost-accuracy plot); the still scene has none
    of it. Catches the motion part missing, shown for a still scene, or plotting frame 0's
    NaN flicker, and flicker left out of the plot's values."""
    import json
    import re

    from harness.report import build_report

    path = _with_box_orbit(small_scene_file, light_orbit=20)
    experiment = tmp_path / "experiment.yaml"
    experiment.write_text(yaml.safe_dump({"techniques": {"sm": {"product": {"res": [64, 256]}},
                                                         "sv": {}}, "warmup": 0}))
    out = tmp_path / "run"
    assert cli.main(["run", str(experiment), "--scene-file", str(path), "--out", str(out),
                     "--quiet"]) == 0
    page = build_report(out).read_text()
    charts = dict(re.findall(r'<script type="application/json" class="chart-spec" '
                             r'data-for="([^"]+)">(.*?)</script>', page, re.S))
    assert "motion-box_orbit" in charts and "motion-box_plane" not in charts
    chart = json.loads(charts["motion-box_orbit"])
    assert [f["title"].split(":")[0] for f in chart["facets"]] == ["mae", "edge_mae per frame",
                                                                    "flicker", "world_flicker"]
    for facet in chart["facets"]:
        assert len(facet["series"]) == 3
        frames = [p["x"] for p in facet["series"][0]["points"]]
        assert frames == ([1, 2, 3] if "flicker" in facet["title"].split(":")[0]
                          else [0, 1, 2, 3])
    sections = {name: page[page.index(f'id="scene-{name}"'):] for name in ("box_orbit",
                                                                            "box_plane")}
    for name, text in sections.items():
        text = text[:text.index("</section>")]
        runs = json.loads(re.search(r'class="scene-data">(.*?)</script>', text, re.S)[1])["runs"]
        moving_scene = name == "box_orbit"
        assert text.count('class="worst-frame"') == (3 if moving_scene else 0)
        assert all((r["values"]["flicker"] is not None) == moving_scene for r in runs)
        if moving_scene:
            assert text.count('alt="strip: V at frame') == sum(
                len(np.load(out / r["array"])["strip_frames"]) for r in result_rows(out)
                if r["scene"] == name)
