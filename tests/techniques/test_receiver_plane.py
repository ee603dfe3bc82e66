"""Receiver-plane depth bias (issue 32 item 3; Isidoro, GDC 2006; Schueler, ShaderX5): with
``bias_mode: receiver_plane`` each filter sample is compared with the receiver plane's own
depth at the texel it reads, depth + g . (c - u), instead of the bound depth - |g| |c - u|
(``bias_mode: slope``). ``bias_mode: adaptive``: tests/techniques/test_adaptive_bias.py."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from harness import config
from harness.scene import build_scene

TILT = 35.0  # degrees: the receiver plane turned about x
LIGHT = [0.95, 0.25, -0.3]  # 67.7 degrees from the plane's normal: grazing


def normal() -> np.ndarray:
    t = np.radians(TILT)
    return np.array([0.0, -np.sin(t), np.cos(t)])


@pytest.fixture(scope="module")
def tilted_plane(tmp_path_factory):
    """A plane tilted 35 degrees under a grazing sun, nothing over it: every pixel lit."""
    folder = tmp_path_factory.mktemp("tilted")
    scene = {"resolution": [128, 128],
             "camera": {"position": [0, -7, 7], "target": [0, 0, 0], "up": [0, 0, 1], "yfov": 50,
                        "near": 0.1, "far": 100},
             "light": {"type": "directional", "direction": LIGHT},
             "objects": [{"shape": "plane", "size": [16, 16], "rotate": [TILT, 0, 0]}]}
    path = folder / "scenes.yaml"
    path.write_text(yaml.safe_dump({"scenes": {"tilted": scene}}))
    return build_scene("tilted", config.load_scenes(path)["tilted"], path)


def test_one_samples_comparison_depth_by_hand():
    """The plane's depth at a sample 10 texels downhill of the point (texels of h = 0.01 world
    units, along the light-space axis the plane falls away along), by hand: the light ray
    through the sample's texel meets the plane t further along the light, t = -h 10 (n . e) /
    (n . d); the receiver-plane extrapolation depth + g . (c - u), g = h tan(theta) per texel
    along that axis (theta the light's angle from the normal), gives the same depth. The bound
    that bias_mode receiver_plane replaces, depth - |g| |c - u|, is 2 g . (c - u) = 0.49 units
    nearer the light here: the over-bias that lets light leak under casters near their receivers."""
    n, d = normal(), np.asarray(LIGHT) / np.linalg.norm(LIGHT)
    e = n - (n @ d) * d
    e = e / np.linalg.norm(e)  # in the map's plane, the way the receiver falls away
    h, texels, point = 0.01, 10.0, np.zeros(3)
    theta = np.arccos(-n @ d)
    assert np.degrees(theta) == pytest.approx(67.737, abs=1e-3)
    # by hand: where the light ray through the sample meets the plane, and its depth
    origin = point + texels * h * e
    t = -(n @ (origin - point)) / (n @ d)
    plane_depth = d @ (origin + t * d) - d @ point
    extrapolated = texels * h * np.tan(theta)
    assert plane_depth == pytest.approx(extrapolated, rel=1e-12)
    assert plane_depth == pytest.approx(0.2443, abs=1e-4)
    assert extrapolated - (-texels * h * np.tan(theta)) == pytest.approx(0.4885, abs=1e-4)


def test_receiver_plane_clears_a_grazing_plane_at_k_64(tilted_plane, evaluate):
    """At k = 64 over the footprint region (up to 64 texels at this angle), the defaults'
    constant bias alone shadows 94 % of the plane; the receiver plane leaves none, with no
    constant bias at all. Over-extrapolated by 10 % (slope_bias 1.1) the downhill samples
    compare deeper than the plane and 94 % are in acne again, where the bound (bias_mode
    slope) at 1.1 leaves none: the comparison depth is the plane's, not a margin. Broken versions
    caught: the knob not reaching the shader (the bound: no acne at 1.1), the sign of g . (c - u)
    flipped (acne at 1.0). (mdsm's window corners' maximum taken as a minimum is not caught
    here: on a plane its selected depths pass either way.)"""
    def acne(**params):
        return evaluate(tilted_plane, "pcf", {"k": 64, **params}).row["acne_pct"]

    assert acne(slope_bias=0.0) > 50.0
    assert acne(bias_mode="receiver_plane") == 0.0
    assert acne(bias_mode="receiver_plane", bias_min=0.0, bias_max=0.0) == 0.0
    assert acne(bias_mode="receiver_plane", bias_min=0.0, bias_max=0.0, slope_bias=1.1) > 50.0
    assert acne(bias_min=0.0, bias_max=0.0, slope_bias=1.1) == 0.0


@pytest.mark.parametrize("technique, params, over", [
    ("mdsm", {"bias": 0.0}, 1.1), ("csm", {"bias": 0.0}, 1.1), ("lispsm", {"k": 9}, 2.0),
    ("psm", {"k": 9}, 2.0), ("gmnpr", {"k": 9}, 2.0)])
def test_every_filtering_map_takes_the_knob(tilted_plane, evaluate, technique, params, over):
    """mdsm (its window's corners), csm and the warps: no acne on the grazing plane with the
    receiver plane (mdsm and csm with no constant bias; the warps keep their default 0.02: in
    a perspective-warped map the plane's depth is projective in the texel, so its tangent plane
    misses by a second-order term, which shadowed 91 to 99.9 % of the plane with no constant
    bias), and the knob reaches each shader (over-extrapolated, by 10 %, or twice for the
    warps' 3 x 3 texels within their constant bias, it shadows the plane's downhill reads:
    lispsm 23 % at 2, the bound 0 % at 2, 5 or 20). Broken version caught: a technique whose
    shader never gets the uniform (no acne when over-extrapolated)."""
    def acne(**more):
        return evaluate(tilted_plane, technique, {**params, "bias_mode": "receiver_plane",
                                                  **more}).row["acne_pct"]

    assert acne() == 0.0
    assert acne(slope_bias=over) > 5.0


def test_a_point_lights_cube_takes_the_knob(tmp_path, evaluate):
    """pcf's cube map (a point light 5 units to the side of the tilted plane, grazing it): with
    the receiver plane at pcf's default constant bias no acne; over-extrapolated by half
    (slope_bias 1.5) 72 % of the plane, where the bound at 2 leaves none. With no constant bias
    the receiver plane alone leaves 4.8 %: a face's texel is projective in the world, as in the
    warped maps. Broken version caught: the cube's shading never gets the uniform."""
    scene = {"resolution": [128, 128],
             "camera": {"position": [0, -7, 7], "target": [0, 0, 0], "up": [0, 0, 1], "yfov": 50,
                        "near": 0.1, "far": 100},
             "light": {"type": "point", "position": [-5, -1, 1.5]},
             "objects": [{"shape": "plane", "size": [16, 16], "rotate": [TILT, 0, 0]}]}
    path = tmp_path / "scenes.yaml"
    path.write_text(yaml.safe_dump({"scenes": {"point": scene}}))
    built = build_scene("point", config.load_scenes(path)["point"], path)

    def acne(**params):
        return evaluate(built, "pcf", {"k": 64, **params}).row["acne_pct"]

    assert acne(bias_mode="receiver_plane") == 0.0
    assert acne(bias_mode="receiver_plane", slope_bias=1.5) > 50.0
    assert acne(slope_bias=2.0) == 0.0
