"""Adaptive depth bias (issue 46 part 4; Dou, Yan, Kerzner, Dai, Wyman, "Adaptive Depth Bias
for Shadow Maps", JCGT 3(4), 2014): with ``bias_mode: adaptive`` every depth read, each PCF
tap too, is compared with the depth at which the light ray through the centre of the texel
read meets the receiver's tangent plane (the G-buffer's point and flat normal), less a
rounding epsilon, instead of the constant plus slope bias (techniques/common/shadow_map.glsl)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from harness import config
from harness.scene import build_scene
from helpers import ROOT

TILT = 35.0  # degrees: the probe's plane turned about x (as test_receiver_plane.py's)
SNAP, ROUNDING = 1.0 / 256.0, 2.0 ** -20  # shadow_map.glsl's ADAPTIVE_SNAP, ADAPTIVE_ROUNDING
CAMERA = {"position": [0, -7, 6], "target": [0, 0, 0.5], "up": [0, 0, 1], "yfov": 50,
          "near": 0.1, "far": 100}
# a gable roof: two 30-degree planes meeting at a ridge along x (a convex crease)
ROOF = [{"shape": "plane", "size": [8, 4], "rotate": [30, 0, 0], "translate": [0, -1.732, 0]},
        {"shape": "plane", "size": [8, 4], "rotate": [-30, 0, 0], "translate": [0, 1.732, 0]}]
# five steps on a floor (risers and treads: concave creases at every riser's foot)
STAIRS = [{"shape": "plane", "size": [12, 12]}] + [
    {"shape": "box", "size": [6, 1, 0.4 * (i + 1)], "translate": [0, -2 + i, 0.2 * (i + 1)]}
    for i in range(5)]


def scene_of(folder, name, objects, light, size=128):
    scene = {"resolution": [size, size], "camera": CAMERA, "light": light, "objects": objects}
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"scenes": {name: scene}}))
    return build_scene(name, config.load_scenes(path)[name], path)


def plane_normal() -> np.ndarray:
    t = np.radians(TILT)
    return np.array([0.0, -np.sin(t), np.cos(t)])


def acne(evaluate, scene, technique, params):
    return evaluate(scene, technique, params).row["acne_pct"]


# -- one receiver's reads by hand ------------------------------------------------------------

def by_hand(view, proj, res, point, normal, centres):
    """float64: the point's map position u, and for each texel centre c the depth, less the
    point's, where the light ray through c (two points of it unprojected from the map's near
    and far planes) meets the plane through the point with that normal; the plane's depth
    slope per texel |g| at u (central differences of the same function)."""
    m = proj @ view
    inverse = np.linalg.inv(m)
    clip = m @ np.append(point, 1.0)
    u = (clip[:2] / clip[3] * 0.5 + 0.5) * res

    def depth(x):
        return -(view @ np.append(x, 1.0))[2]

    def offset(c):
        ndc = np.asarray(c, float) * 2.0 / res - 1.0
        near, far = (inverse @ np.array([*ndc, z, 1.0]) for z in (-1.0, 1.0))
        near, far = near[:3] / near[3], far[:3] / far[3]
        t = normal @ (point - near) / (normal @ (far - near))
        return depth(near + t * (far - near)) - depth(point)

    h = 1e-3
    g = np.array([(offset(u + e) - offset(u - e)) / (2 * h) for e in (np.array([h, 0.0]),
                                                                         np.array([0.0, h]))])
    return u, np.array([offset(c) for c in centres]), float(np.linalg.norm(g)), depth(point)


def probe(frustum, res, point, normal, first, step, reads):
    """tests/data/adaptive_bias_probe.frag.glsl over a reads x 1 target: per read (x), the
    shader's plane_offset, receiver_bias (bias_mode adaptive), the point's depth and |g|."""
    from OpenGL import GL

    from harness.gl.framebuffer import Framebuffer
    from harness.gl.geometry import FullscreenTriangle
    from harness.gl.shaders import HARNESS_GLSL, Program
    from harness.technique import reset_gl_state

    program = Program(HARNESS_GLSL / "fullscreen.vert.glsl",
                      ROOT / "tests" / "data" / "adaptive_bias_probe.frag.glsl")
    target = Framebuffer(reads, 1, (GL.GL_RGBA32F,), depth=False)
    triangle = FullscreenTriangle()
    try:
        target.bind()
        GL.glDisable(GL.GL_DEPTH_TEST)
        program.use().set(light_view=frustum.view, light_proj=frustum.proj, map_res=float(res),
                          light_is_ortho=frustum.is_ortho, slope_bias=1.0, depth_precision=0.0,
                          normal_offset=0.0, bias_mode=2, point=point, point_normal=normal,
                          first_centre=first, step=step)
        triangle.draw()
        return target.read()[0].astype(np.float64)
    finally:
        triangle.release()
        target.release()
        program.release()
        reset_gl_state()


@pytest.mark.parametrize("light", [
    {"type": "directional", "direction": [0.95, 0.25, -0.3]},
    {"type": "spot", "position": [-5, -1, 1.5], "target": [0, 0, 0], "fov": 90}])
def test_one_receivers_adaptive_bias_by_hand(tmp_path, gl_context, light):
    """A point of a plane tilted 35 degrees, grazed by a directional light (67.7 degrees from
    its normal: an orthographic map) or lit by a spot light (a perspective one), map 1024:
    for its own texel and reads up to 6 and 3 texels away along each axis, the depth at which
    the light ray through each texel centre meets the plane, computed here in float64 (ray
    unprojected, plane intersected), equals the shader's plane_offset within 1 % of the
    epsilon (float32), and the read's bias is epsilon - offset, epsilon = |g| / 256 +
    2^-20 |offset| with |g| the plane's depth slope per texel by central differences here.
    Broken versions caught: the texel centre off by half a texel (the offset misses by |g| / 2,
    about 128 epsilon), the normal ignored (a plane facing the light: offset 0), the
    perspective division left out (the spot light's offsets)."""
    from harness.scene.transforms import fit_light

    scene = scene_of(tmp_path, "tilted", [{"shape": "plane", "size": [16, 16],
                                           "rotate": [TILT, 0, 0]}], light)
    res = 1024
    frustum = fit_light(scene, res)
    t = np.radians(TILT)
    point = np.array([0.3, 0.7 * np.cos(t), 0.7 * np.sin(t)])  # on the plane
    normal = plane_normal()
    assert abs(normal @ point) < 1e-12
    u = by_hand(frustum.view, frustum.proj, res, point, normal, [])[0]
    first, step, reads = np.floor(u) + 0.5 - np.array([6.0, 3.0]), np.array([2.0, 1.0]), 7
    centres = first + np.arange(reads)[:, None] * step
    _, offsets, slope, depth = by_hand(frustum.view, frustum.proj, res, point, normal, centres)
    epsilon = SNAP * slope + ROUNDING * np.abs(offsets)
    shader = probe(frustum, res, point.astype(np.float32), normal.astype(np.float32), first,
                   step, reads)
    assert shader[:, 2] == pytest.approx(depth, rel=1e-6)
    assert shader[:, 3] == pytest.approx(slope, rel=1e-4)
    assert np.ptp(offsets) > 5 * slope  # the reads reach far up and down the plane
    assert np.abs(shader[:, 0] - offsets).max() < 0.01 * epsilon.min()
    assert np.abs(shader[:, 1] - (epsilon - offsets)).max() < 0.01 * epsilon.min()


def test_mdsm_window_depths_take_the_nearest_corner(tmp_path, evaluate):
    """mdsm's window depths (``extra: min``: the nearest depth of the 3 x 3 window, which on a
    plane lies at the window's corner nearest the light) are compared with the tangent
    plane's depth at the window's most lenient corner: on the plane tilted 35 degrees under
    the grazing sun, 0 % acne with no constant. Broken version caught: the corners' minimum
    taken as their maximum (the window's farthest corner: acne)."""
    scene = scene_of(tmp_path, "tilted", [{"shape": "plane", "size": [16, 16],
                                           "rotate": [TILT, 0, 0]}],
                     {"type": "directional", "direction": [0.95, 0.25, -0.3]})
    for params in ({"extra": "min"}, {"n": 3}):  # the 3 x 3 window, as measured (q 9)
        assert acne(evaluate, scene, "mdsm", {**params, "q": 9, "bias_mode": "adaptive"}) == 0.0


# -- creased receivers ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def creases(tmp_path_factory, gl_context):
    folder = tmp_path_factory.mktemp("creases")
    grazing = {"type": "directional", "direction": [0.3, 1, -0.25]}  # 14 degrees high
    return {"roof": scene_of(folder, "roof", ROOF, grazing),
            "stairs": scene_of(folder, "stairs", STAIRS, grazing)}


@pytest.mark.parametrize("technique", ["lispsm", "psm", "gmnpr"])
def test_a_roof_ridge_in_a_warped_map_needs_no_constant(creases, evaluate, technique):
    """The roof ridge under a grazing sun (14 degrees high), the warps with 3 x 3 PCF and no
    constant bias: in a perspective-warped map the plane's depth is projective in the texel,
    so the slope bound |g| |c - u| (measured: lispsm 0.65 %, psm 0.15 %, gmnpr 13.2 % acne)
    and the extrapolated plane (25.4 %, 23.7 %, 99.99 %) both shadow the lit roof, while the
    tangent plane met on each read's own light ray is exact on both faces and across the
    ridge (0 %): adaptive needs no constant in scene units. Broken versions caught: the normal
    ignored, the perspective division left out, the epsilon's sign flipped (and, for gmnpr,
    no epsilon at all); not the texel centre off by half a texel (the by-hand test and
    the ones below catch it)."""
    roof, unbiased = creases["roof"], {"k": 9, "bias": 0.0}
    assert acne(evaluate, roof, technique, {**unbiased, "bias_mode": "slope"}) > 0.1
    assert acne(evaluate, roof, technique, {**unbiased, "bias_mode": "receiver_plane"}) > 10.0
    assert acne(evaluate, roof, technique, {"k": 9, "bias_mode": "adaptive"}) == 0.0


def test_pcf_on_creases_convex_and_concave(creases, evaluate):
    """pcf at k = 16 under the same sun. On an orthographic map the tangent plane's depth at
    a texel centre is the receiver plane's extrapolation exactly, so adaptive is receiver_plane
    without its constant: on the roof ridge (a convex crease: the other face lies below the
    plane, so no read finds it nearer) all three modes leave 0 % acne; on the stairs each
    riser's foot is a concave crease, where reads of the tread in front of it (above the
    riser's plane) find it nearer than the plane. With the region of res_factor 1 and min_size
    1 texel (the defaults before issue 46) adaptive leaves 4.43 % acne, receiver_plane without
    its constant 4.44 % (3.70 % with its [0.02, 0.04]), the slope bound 2.44 %; with the
    default region (half the footprint, at least a quarter texel) the slope bound leaves none
    (0 %: no read reaches across the crease far enough to beat the bound), adaptive 2.91 %,
    receiver_plane without its constant 2.92 %. The limitation of Dou et al.'s method (and of
    the receiver plane), not a defect of the implementation: it is why slope stays the default
    (docs/techniques.md). Broken versions caught: the texel centre off by half a texel, the
    normal ignored, the epsilon's sign flipped, the constant still added under adaptive (less
    acne than receiver_plane without it); the default region back at res_factor 1 and min_size
    1 (slope 2.44 %)."""
    roof, stairs = creases["roof"], creases["stairs"]
    for mode in ("slope", "receiver_plane", "adaptive"):
        assert acne(evaluate, roof, "pcf", {"k": 16, "bias_mode": mode}) == 0.0, mode
    for region in ({}, {"res_factor": 1.0, "min_size": 1.0}):
        slope = acne(evaluate, stairs, "pcf", {"k": 16, **region})
        plane = acne(evaluate, stairs, "pcf", {"k": 16, "bias_mode": "receiver_plane",
                                               "bias_min": 0.0, "bias_max": 0.0, **region})
        adaptive = acne(evaluate, stairs, "pcf", {"k": 16, "bias_mode": "adaptive", **region})
        assert (slope == 0.0) if not region else (1.0 < slope), (region, slope)
        assert 1.0 < adaptive and slope < adaptive
        assert adaptive == pytest.approx(plane, abs=0.05)


# -- every map technique takes the mode ------------------------------------------------------

HUGE = {"bias": 1000.0, "slope_bias": 64.0}
HUGE_PCF = {"bias_min": 1000.0, "bias_max": 1000.0, "slope_bias": 64.0}


def shadow_kept(evaluate, scene, technique, mode) -> tuple[float, float]:
    """With the huge terms: the fraction of the reference's shadow (V_ref = 0) that V keeps
    (V < 0.5), and acne_pct."""
    e = evaluate(scene, technique, {**(HUGE_PCF if technique == "pcf" else HUGE),
                                    "bias_mode": mode})
    shadow = e.mask & (e.reference.visibility == 0)
    assert shadow.sum() > 100
    return float(np.mean(e.visibility[shadow] < 0.5)), e.row["acne_pct"]


@pytest.mark.parametrize("technique", ["sm", "pcf", "mdsm", "csm", "silhouette", "psm",
                                       "lispsm", "gmnpr"])
def test_adaptive_takes_no_constant_and_no_slope_term(scene_at, evaluate, technique):
    """box_plane at 128 x 128, map 1024, with a constant bias of 1000 scene units and
    slope_bias 64: under slope every shadow is biased away (none of the reference's shadow
    kept), under adaptive neither term is read and the shadow is there (over 95 % of it kept,
    no acne). Catches a technique whose shader never gets bias_mode (the shadow gone) or one
    that still adds the constant under adaptive."""
    scene = scene_at("box_plane", 128)
    assert shadow_kept(evaluate, scene, technique, "slope")[0] == 0.0
    kept, acne_pct = shadow_kept(evaluate, scene, technique, "adaptive")
    assert kept > 0.95 and acne_pct == 0.0, (kept, acne_pct)


@pytest.mark.parametrize("technique", ["sm", "pcf"])
def test_a_point_lights_cube_takes_the_mode(evaluate, technique):
    """The same on a point light's cube (hard_point_seam: a bar's floor shadow across two
    faces, 128 x 128, map 1024)."""
    path = ROOT / "experiments" / "hard_cases" / "scenes.yaml"
    scene = build_scene("hard_point_seam", config.load_scenes(path)["hard_point_seam"], path)
    assert shadow_kept(evaluate, scene, technique, "slope")[0] == 0.0
    kept, acne_pct = shadow_kept(evaluate, scene, technique, "adaptive")
    assert kept > 0.95 and acne_pct == 0.0, (kept, acne_pct)
