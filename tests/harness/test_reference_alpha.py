"""The reference with alpha-tested casters (issue 48): shadow rays go on past cut-out hits.
The shipped ``alpha_checker`` scene (a card cut out by a checker over a ground plane under a
directional light) against its exact visibility computed here, in float64, from the scene's
numbers alone: each sample's camera ray, its ground point projected along the light to the
card's plane, the sampling rule there."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness import config as cfg
from harness.scene import build_scene, load_scene
from harness.scene.alpha import pattern_texture, sample_alpha
from harness.scene.transforms import look_at
from harness.truth import cutouts
from harness.truth import reference as ref_mod
from harness.truth.reference import compute_reference

TIE = 1e-3  # alpha within this of the cutoff: a tie
# a point within this of an edge (scene units; the card is 2 wide): a tie. Mitsuba's float32
# ray-triangle test was seen to hit the card 1.7e-4 outside its edge (the shadow ray 2 units
# long, both renderers agreeing on its origin to 1e-6)
EDGE = 1e-3


def exact_visibility(scene, fx: np.ndarray, fy: np.ndarray):
    """(V, tie) at film positions (fx, fy) in pixels: 1 where the camera ray meets the card
    or the ground outside the card's cut-out shadow (or nothing), 0 in it; tie where the
    sample lies within float32's reach of a decision (the card's or the ground's edge, the
    card's border seen from the ground point, alpha at the cutoff)."""
    cam, (ground, card) = scene.config.camera, scene.config.objects
    view = look_at(cam.position, cam.target, cam.up)
    right, up, forward = view[0, :3], view[1, :3], -view[2, :3]
    half = math.tan(math.radians(cam.yfov) / 2)
    ndc_x, ndc_y = 2 * fx / scene.width - 1, 1 - 2 * fy / scene.height
    d = (forward + (ndc_x * half * scene.width / scene.height)[..., None] * right
         + (ndc_y * half)[..., None] * up)
    origin = np.asarray(cam.position, np.float64)
    height = card.translate[2]
    (cx, cy), (gx, gy) = np.asarray(card.size) / 2, np.asarray(ground.size) / 2

    def on_plane(z, sx, sy):
        point = origin + ((z - origin[2]) / d[..., 2])[..., None] * d
        inside = (np.abs(point[..., 0]) <= sx) & (np.abs(point[..., 1]) <= sy)
        edge = np.minimum(np.abs(np.abs(point[..., 0]) - sx), np.abs(np.abs(point[..., 1]) - sy))
        return point, inside, edge < EDGE

    seen, on_card, card_edge = on_plane(height, cx, cy)
    point, on_ground, ground_edge = on_plane(0.0, gx, gy)
    light = scene.light
    to_light = -light.direction if light.type == "directional" else light.position - point
    q = point + (height / to_light[..., 2])[..., None] * to_light  # its light ray at the card
    within = (np.abs(q[..., 0]) <= cx) & (np.abs(q[..., 1]) <= cy)
    border = np.minimum(np.abs(np.abs(q[..., 0]) - cx), np.abs(np.abs(q[..., 1]) - cy)) < EDGE
    w, h = card.alpha.size
    texture, cutoff = pattern_texture(card.alpha.pattern, w, h), card.alpha.cutoff

    def alpha_at(p):  # PLANE_UV
        return sample_alpha(texture, np.stack([p[..., 0] / (2 * cx) + 0.5,
                                               0.5 - p[..., 1] / (2 * cy)], -1))

    alpha, seen_alpha = alpha_at(q), alpha_at(seen)
    seen_tie = on_card & (np.abs(seen_alpha - cutoff) < TIE)
    on_card = on_card & (seen_alpha >= cutoff)  # the camera sees the ground through the holes
    shadowed = on_ground & ~on_card & within & (alpha >= cutoff)
    tie = card_edge | seen_tie | ((ground_edge | border) & ~on_card) | (
        on_ground & ~on_card & within & (np.abs(alpha - cutoff) < TIE))
    return np.where(shadowed, 0.0, 1.0), tie


def sample_positions(mi, scene, seed: int = 0):
    """Film positions of every pixel's one sample (the reference's own sampler)."""
    lane = np.arange(scene.width * scene.height, dtype=np.uint32)
    x, y = lane % scene.width, lane // scene.width
    if cutouts.jit_variant(mi):
        fx, fy = ref_mod.film_position(mi, scene, mi.UInt32(x), mi.UInt32(y),
                                       mi.UInt32(0 * lane), 1, seed)
        return (np.asarray(fx, np.float64).reshape(scene.height, scene.width),
                np.asarray(fy, np.float64).reshape(scene.height, scene.width))
    pos = [ref_mod.film_position(mi, scene, int(i), int(j), 0, 1, seed) for i, j in zip(x, y)]
    return (np.array([p[0] for p in pos], np.float64).reshape(scene.height, scene.width),
            np.array([p[1] for p in pos], np.float64).reshape(scene.height, scene.width))


def with_light(scene, light: dict):
    config = scene.config.model_copy(update={"light": cfg.Scene.model_validate(
        {**scene.config.model_dump(), "light": light}).light})
    return build_scene(scene.name, config, scene.source)


# the directional light's shadow, about, from a point light 3 units from the card along it
POINT = {"type": "point", "position": [3.0, -1.8, 4.5]}


@pytest.mark.parametrize("variant, size, light", [
    ("llvm_ad_rgb", 128, None), ("scalar_rgb", 32, None), ("llvm_ad_rgb", 128, POINT)])
def test_the_checker_card_shadow_is_exact_but_at_ties(variant, size, light):
    """One sample a pixel, so V is that sample's visibility: equal to the exact one at every
    pixel but ties, and ties few (108 of 16,384 at 128^2, 7 of them differing). Catches (each
    tried): the loop going on past every cut-out hit (no shadow: 1,924 pixels wrong at 128^2;
    scalar_rgb 136 at 32^2), stopping at every hit (the card's whole square: 1,924; scalar
    104), the cut-out read with v upward (3,848). A point light's rays go on toward its
    position from each cut-out hit."""
    scene = load_scene("alpha_checker").with_resolution(size, size)
    if light is not None:
        scene = with_light(scene, light)
    ref = compute_reference(scene, samples=1, use_cache=False, variant=variant)
    mi = ref_mod.mitsuba_module(variant)
    exact, tie = exact_visibility(scene, *sample_positions(mi, scene))
    wrong = ref.visibility != exact
    assert (exact == 0).sum() > size * size // 50  # the shadow is in view
    assert not (wrong & ~tie).any(), f"{(wrong & ~tie).sum()} pixels wrong off the ties"
    assert tie.sum() <= 0.01 * size * size, f"{tie.sum()} ties"
    assert ref.bounded_rays == 0


def test_a_scene_traced_again_builds_no_kernel():
    """Once a scene with cut-outs has been traced, its later traces take their kernels from
    Dr.Jit's kernel cache. Catches the cut-out table's one-entry arrays (a scene of one mask:
    every shipped one) read as scalar loads, whose IR carries the alignment of wherever the
    array was allocated: then most traces built a new kernel (0.12 s of LLVM at 512 x 512,
    half a card's trace, and why cut-outs cost 3.3x the opaque trace, not 2x)."""
    import drjit as dr

    scene = load_scene("alpha_checker").with_resolution(32, 32)
    mi = ref_mod.mitsuba_module("llvm_ad_rgb")
    mscene = mi.load_dict(ref_mod.mitsuba_scene_dict(scene, mi, 4))
    ref_mod.trace_visibility(mi, mscene, scene, 4, 0)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()  # emptied
        for _ in range(4):
            ref_mod.trace_visibility(mi, mscene, scene, 4, 0)
        built = [k["hash"] for k in dr.kernel_history()
                 if k["type"] == dr.KernelType.JIT and not k["cache_hit"]]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert not built, f"{len(built)} kernels built again in 4 traces"


def test_the_textures_bytes_are_in_the_cache_key(tmp_path):
    """Two scenes alike but for their cut-out's texels have different reference cache keys;
    an opaque scene's key is as before cut-outs (no ``cutouts`` term). Catches a key of the
    scene description alone (a procedural pattern's texels change with its code)."""
    scene = load_scene("alpha_checker")
    key = ref_mod.cache_key(scene, 4, 0)
    part = scene.parts[1]
    other = type(part.alpha)(255 - part.alpha.texture, part.alpha.cutoff, "inverted")
    changed = type(scene)(scene.name, scene.config,
                          [scene.parts[0], type(part)(**{**part.__dict__, "alpha": other})],
                          scene.light, scene.key, scene.source)
    assert ref_mod.cache_key(changed, 4, 0) != key


@pytest.mark.parametrize("variant", ["llvm_ad_rgb", "scalar_rgb"])
def test_a_ray_at_the_bound_is_counted_occluded(variant, monkeypatch):
    """A card that is all cut out (a checker at cutoff 1: alpha reaches 1 only at its opaque
    texels' centres) casts no shadow; with the bound at one cut-out hit, every shadow ray that
    passes it stops there, is counted occluded, and is counted in ``bounded_rays``. Catches a
    bound that lets rays through uncounted, or one that counts rays that met nothing."""
    scene = load_scene("alpha_checker").with_resolution(24, 24)
    card = scene.parts[1]
    clear = type(card.alpha)(card.alpha.texture, 1.0, "all cut out")
    scene = type(scene)(scene.name, scene.config,
                        [scene.parts[0], type(card)(**{**card.__dict__, "alpha": clear})],
                        scene.light, scene.key, scene.source)
    free = compute_reference(scene, samples=1, use_cache=False, variant=variant)
    assert (free.visibility == 1).all() and free.bounded_rays == 0
    monkeypatch.setattr(cutouts, "MAX_CUTOUT_HITS", 1)
    with pytest.warns(RuntimeWarning, match="cut-out hits and were counted occluded"):
        bounded = compute_reference(scene, samples=1, use_cache=False, variant=variant)
    assert bounded.bounded_rays == (bounded.visibility == 0).sum() > 10
