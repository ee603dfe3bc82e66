"""The Mitsuba reference: camera match, correctness against an independent ray caster, cache."""

import warnings

import numpy as np
import pytest

from harness import reference as ref_mod
from harness.reference import compute_reference
from harness.technique import Frame

SHIPPED = ["sphere_plane", "box_plane", "pins", "castle", "crowd", "terrain_long"]


def gbuffer_arrays(scene):
    """The GL side's G-buffer arrays of a scene (a Frame made and released)."""
    frame = Frame(scene)
    try:
        return frame.arrays
    finally:
        frame.release()


def all_scene_names():
    from harness import config
    from conftest import SCENE_FILE

    return list(config.load_scenes(SCENE_FILE))


@pytest.mark.parametrize("name", all_scene_names())
def test_gl_and_mitsuba_coverage_agree(name, scene_at, gl_context):
    scene = scene_at(name, 160, 120)
    gl_covered = gbuffer_arrays(scene).covered
    ref = compute_reference(scene, samples=4)
    agreement = (gl_covered == ref.covered).mean()
    assert agreement >= 0.999, f"{name}: {agreement:.5f}"
    assert 0.05 < gl_covered.mean()  # the scene is in view


def test_shipped_scenes_present():
    assert set(SHIPPED) <= set(all_scene_names())


def _box_occludes(points, to_light, lo, hi):
    """Independent slab test: does the ray p + t * to_light (t > 0) hit the box [lo, hi]?"""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / to_light
        t0 = (lo - points) * inv
        t1 = (hi - points) * inv
    tmin = np.nanmax(np.minimum(t0, t1), axis=-1)
    tmax = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (tmax >= np.maximum(tmin, 1e-6))


def test_reference_matches_an_independent_ray_caster(scene_at, gl_context):
    """box_plane: the box is the only occluder; its shadow on the plane by slab tests."""
    scene = scene_at("box_plane", 192)
    arrays = gbuffer_arrays(scene)
    ref = compute_reference(scene, samples=16)
    on_plane = arrays.covered & ref.covered & (np.abs(arrays.position[..., 2]) < 1e-4)
    to_light = np.broadcast_to(-scene.light.direction, arrays.position.shape)
    shadowed = _box_occludes(arrays.position.astype(np.float64), to_light,
                             np.array([-0.5, -0.5, 1.0]), np.array([0.5, 0.5, 2.0]))
    expected = np.where(shadowed, 0.0, 1.0)
    interior = on_plane & ((ref.visibility == 0) | (ref.visibility == 1))
    assert shadowed[on_plane].mean() > 0.01
    assert (ref.visibility[interior] == expected[interior]).mean() > 0.999
    # boundary pixels are fractional in the reference: it averages over the pixel's area
    assert ((ref.visibility > 0) & (ref.visibility < 1) & on_plane).sum() > 20


def test_reference_is_cached(scene_at, tmp_path, monkeypatch):
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path))
    scene = scene_at("box_plane", 48)
    first = compute_reference(scene, samples=4)
    second = compute_reference(scene, samples=4)
    assert not first.cached and second.cached
    assert np.array_equal(first.visibility, second.visibility)
    assert len(list((tmp_path / "reference").glob("*.npz"))) == 1
    other = compute_reference(scene, samples=16)  # another key: traced again
    assert not other.cached


def test_direct_image_only_when_the_scene_asks(scene_at):
    assert compute_reference(scene_at("sphere_plane", 64), samples=4).direct.shape == (64, 64, 3)
    assert compute_reference(scene_at("box_plane", 64), samples=4).direct is None


def test_direct_image_is_lambert_times_visibility(scene_at, gl_context):
    """Mitsuba's direct integrator and the GL-side shading agree where V_ref is 0 or 1."""
    from harness import metrics

    scene = scene_at("sphere_plane", 96)
    a = gbuffer_arrays(scene)
    ref = compute_reference(scene, samples=16)
    shaded = metrics.shade(ref.visibility, a.normal, a.position, a.albedo, scene.light,
                           ambient=0.0)[..., 0]
    direct = ref.direct[..., 0]
    interior = a.covered & ref.covered & ((ref.visibility == 0) | (ref.visibility == 1))
    from scipy import ndimage
    interior &= ~ndimage.binary_dilation(~a.covered, iterations=2)
    rel = np.abs(direct - shaded)[interior] / np.maximum(shaded[interior], 0.05)
    assert np.median(rel) < 0.02


def test_llvm_older_than_16_falls_back_to_scalar_with_warning(monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setattr(ref_mod, "_llvm_libraries", lambda: [(15, "/usr/lib/libLLVM-15.so")])
    with pytest.warns(RuntimeWarning, match="libllvm19"):
        assert ref_mod.choose_variant() == "scalar_rgb"


def test_llvm_19_present_gives_llvm_variant(monkeypatch):
    libraries = ref_mod._llvm_libraries()
    if not libraries or libraries[0][0] < 16:
        pytest.fail("CI installs libllvm19 (Makefile); no LLVM >= 16 library was found")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert ref_mod.choose_variant() == "llvm_ad_rgb"


def test_scalar_and_llvm_variants_agree(scene_at, tmp_path, monkeypatch):
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path))
    scene = scene_at("box_plane", 24)
    fast = compute_reference(scene, samples=4, variant="llvm_ad_rgb", use_cache=False)
    slow = compute_reference(scene, samples=4, variant="scalar_rgb", use_cache=False)
    ref_mod._mitsuba("llvm_ad_rgb")
    assert np.array_equal(fast.covered, slow.covered)
    assert np.abs(fast.visibility - slow.visibility).max() <= 0.25  # at most one sample of 4


def test_samples_must_be_square(scene_at):
    with pytest.raises(ValueError, match="square"):
        compute_reference(scene_at("box_plane", 32), samples=8)
