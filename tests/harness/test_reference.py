"""The Mitsuba reference: camera match, correctness against an independent ray caster, cache."""

import dataclasses
import errno
import math
import re
import warnings

import numpy as np
import pytest
import yaml

from harness.truth import reference as ref_mod
from harness.truth import variant as variant_mod
from harness.truth.reference import UntraceableSceneError, compute_reference
from harness.scene import Light
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
    from helpers import SCENE_FILE

    from harness import config

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


def _box_occludes(points, to_light, lo, hi, t_max=np.inf):
    """Independent slab test: does the ray p + t * to_light (0 < t < t_max) hit the box?"""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / to_light
        t0 = (lo - points) * inv
        t1 = (hi - points) * inv
    tmin = np.nanmax(np.minimum(t0, t1), axis=-1)
    tmax = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (tmax >= np.maximum(tmin, 1e-6)) & (tmin < t_max)


SPOT_ABOVE_THE_BOX = Light("spot", np.array([-0.3, 0.2, -1.0]) / np.linalg.norm([-0.3, 0.2, -1.0]),
                           np.array([0.6, -0.4, 4.0]), 120.0, 4.0)


@pytest.mark.parametrize("light", ["directional", "spot"])
def test_reference_matches_an_independent_ray_caster(light, scene_at, gl_context):
    """box_plane: the box is the only occluder; its shadow on the plane by slab tests, under
    the scene's directional light and under a spot light above the box (the shadow ray ends at
    the light). Catches a kernel that offsets samples or strata wrongly, tests the wrong
    pixels' rays, or shoots the spot light's shadow ray along its axis instead of to its
    position (seen failing: spawn_ray(-direction) for the spot light gives 0.975 agreement)."""
    scene = scene_at("box_plane", 192)
    if light == "spot":
        scene = dataclasses.replace(scene, light=SPOT_ABOVE_THE_BOX)
    arrays = gbuffer_arrays(scene)
    ref = compute_reference(scene, samples=16, use_cache=False)
    on_plane = arrays.covered & ref.covered & (np.abs(arrays.position[..., 2]) < 1e-4)
    points = arrays.position.astype(np.float64)
    if light == "spot":
        to_light, t_max = scene.light.position - points, 1.0
    else:
        to_light, t_max = np.broadcast_to(-scene.light.direction, points.shape), np.inf
    shadowed = _box_occludes(points, to_light, np.array([-0.5, -0.5, 1.0]),
                             np.array([0.5, 0.5, 2.0]), t_max)
    expected = np.where(shadowed, 0.0, 1.0)
    interior = on_plane & ((ref.visibility == 0) | (ref.visibility == 1))
    assert shadowed[on_plane].mean() > 0.01
    assert (ref.visibility[interior] == expected[interior]).mean() > 0.999
    # boundary pixels are fractional in the reference: it averages over the pixel's area
    fractional = (ref.visibility > 0) & (ref.visibility < 1) & on_plane
    assert fractional.sum() > 20
    # ... with 16 stratified samples: V is a multiple of 1/16 where all samples hit the plane
    assert np.allclose((ref.visibility[fractional] * 16) % 1, 0, atol=1e-5)


# A plate 1 unit over a ground plane under a grazing directional light (3 units across per unit
# down) casts the rectangle [2, 4] x [-1, 1] shifted by the plate's offset; a camera 9 units over
# (3, 0, 0) looking straight down, its up +y, sees [1, 5] x [-2, 2] of the ground and nothing of
# the plate (which covers x <= 1.02 at height 1, where the view starts at 1.22). At 64 px a pixel
# is 1/16 unit and pixel (row, column) is [1 + column/16, 1 + (column + 1)/16] x [2 - (row + 1)/16,
# 2 - row/16]. The plate's offset puts each shadow edge 0.36 or 0.64 of the way across its pixels.
EDGE_PIXELS = 64
EDGE_PIXEL = 4 / EDGE_PIXELS
EDGE_OFFSET = (0.36 * EDGE_PIXEL, 0.64 * EDGE_PIXEL)
EDGE_SCENE = {
    "resolution": [EDGE_PIXELS, EDGE_PIXELS],
    "camera": {"position": [3, 0, 9], "target": [3, 0, 0], "up": [0, 1, 0],
               "yfov": math.degrees(2 * math.atan(2 / 9)), "near": 0.1, "far": 100},
    "light": {"type": "directional", "direction": [3, 0, -1]},
    "effects": ["shadow"],
    "objects": [{"shape": "plane", "size": [20, 20]},
                {"shape": "plane", "size": [2, 2], "translate": [*EDGE_OFFSET, 1]}],
}


def _overlap(low, high, shadow_low, shadow_high):
    """Length of [low, high] inside [shadow_low, shadow_high] (arrays broadcast)."""
    return np.clip(np.minimum(high, shadow_high) - np.maximum(low, shadow_low), 0, None)


def _strata_lit_fraction(side: int) -> np.ndarray:
    """(row, column, j, i): the exact lit fraction of each of the side x side strata of each
    pixel of EDGE_SCENE (stratum j, i: the j-th from the pixel's top, the i-th from its left)."""
    n, p, stratum = EDGE_PIXELS, EDGE_PIXEL, EDGE_PIXEL / side
    cells = np.arange(n)[:, None] + np.arange(side)[None, :] / side  # pixel + stratum start
    x_low = 1 + cells * p
    y_high = 2 - cells * p
    shadow_x = _overlap(x_low, x_low + stratum, 2 + EDGE_OFFSET[0], 4 + EDGE_OFFSET[0]) / stratum
    shadow_y = _overlap(y_high - stratum, y_high, -1 + EDGE_OFFSET[1], 1 + EDGE_OFFSET[1]) / stratum
    return 1 - shadow_y[:, None, :, None] * shadow_x[None, :, None, :]


def test_reference_averages_the_pixel_area_by_jittered_strata(tmp_path):
    """Each sample of a pixel's 16 is uniform in its own 1/4 x 1/4 stratum, so along a straight
    edge V_ref has the pixel's exact lit area as its mean and each stratum adds a Bernoulli
    variance g (1 - g) / 256 (g: the stratum's lit fraction, computed exactly here). Per edge
    (about 31 pixels, all crossed 0.36 or 0.64 of the way) the summed error is within 4 of its
    standard deviations, and the squared errors sum to 0.35 .. 2.2 times the variance (chi-square
    with 31 degrees of freedom: each bound one in 1000). Catches samples at the strata corners
    (jitter dropped: a shift of 1/8 px, V 0.5 on every edge pixel, 9 deviations off), at their
    centres (V 0.25 or 0.75, no spread), or shifted by 1/8 px with their jitter kept."""
    from harness import config
    from harness.scene import build_scene

    path = tmp_path / "edge.yaml"
    path.write_text(yaml.safe_dump({"scenes": {"edge": EDGE_SCENE}}))
    scene = build_scene("edge", config.load_scenes(path)["edge"], path)
    ref = compute_reference(scene, samples=16, use_cache=False)
    assert ref.covered.all()
    lit = _strata_lit_fraction(4)
    expected = lit.mean(axis=(2, 3))
    variance = (lit * (1 - lit)).sum(axis=(2, 3)) / 16 ** 2
    partial = lambda fractions: (fractions > 0) & (fractions < 1)  # noqa: E731
    lit_rows, lit_columns = lit.min(axis=(1, 3)), lit.min(axis=(0, 2))  # (row, j), (column, i)
    rows_crossed = np.flatnonzero(partial(lit_rows).any(axis=1))
    columns_crossed = np.flatnonzero(partial(lit_columns).any(axis=1))
    assert len(rows_crossed) == len(columns_crossed) == 2  # the four edges, each in one line
    inner_rows = np.arange(rows_crossed[0] + 1, rows_crossed[1])
    inner_columns = np.arange(columns_crossed[0] + 1, columns_crossed[1])
    edges = {f"column {c}": (inner_rows, c) for c in columns_crossed}
    edges.update({f"row {r}": (r, inner_columns) for r in rows_crossed})
    for edge, pixels in edges.items():
        error = ref.visibility[pixels] - expected[pixels]
        assert np.isin(np.round(expected[pixels], 6), (0.36, 0.64)).all()
        deviations = error.sum() / math.sqrt(variance[pixels].sum())
        spread = (error ** 2).sum() / variance[pixels].sum()
        assert abs(deviations) < 4 and 0.35 < spread < 2.2, (edge, deviations, spread)


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
    from harness.truth import metrics

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
    monkeypatch.setattr(variant_mod, "_llvm_libraries", lambda: [(15, "/usr/lib/libLLVM-15.so")])
    with pytest.warns(RuntimeWarning, match="libllvm19"):
        assert variant_mod.choose_variant() == "scalar_rgb"


def test_llvm_19_present_gives_llvm_variant(monkeypatch):
    libraries = variant_mod._llvm_libraries()
    if not libraries or libraries[0][0] < 16:
        pytest.fail("CI installs libllvm19 (Makefile); no LLVM >= 16 library was found")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert variant_mod.choose_variant() == "llvm_ad_rgb"


def test_scalar_and_llvm_variants_agree(scene_at, tmp_path, monkeypatch):
    """The scalar fallback runs the same per-pixel code with the same random numbers, so both
    variants give the same V (one pixel of slack for float rounding on an edge; none seen here).
    Catches a scalar path drawing other samples (seen failing: seeding the scalar PCG32 with
    pixel + 1 changes 8 of these 4096 pixels; seeds 1, 2, 3 change 13 or 14)."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path))
    scene = scene_at("box_plane", 64)
    fast = compute_reference(scene, samples=4, variant="llvm_ad_rgb", use_cache=False)
    slow = compute_reference(scene, samples=4, variant="scalar_rgb", use_cache=False)
    ref_mod.mitsuba_module("llvm_ad_rgb")
    assert np.array_equal(fast.covered, slow.covered)
    assert (fast.visibility != slow.visibility).sum() <= 1
    assert np.abs(fast.visibility - slow.visibility).max() <= 0.25  # at most one sample of 4


def test_each_sample_lane_draws_the_numbers_a_loop_over_the_strata_draws(scene_at):
    """One lane per sample (issue 36, item 3): sample s of a pixel must use the numbers 2s and
    2s + 1 of the pixel's PCG32 stream, the numbers the former loop over the strata drew in
    turn, so the reference is the same as before, bit for bit. The expected positions come from
    one PCG32 stream drawn in order, 16 strata of pixel (5, 3). Catches the stream advanced by
    s instead of 2s (seen failing: sample 1 reused sample 0's y jitter as its x jitter)."""
    import drjit as dr

    mi = ref_mod.mitsuba_module("llvm_ad_rgb")
    scene = scene_at("box_plane", 32, 24)
    samples, side, seed, x, y = 16, 4, 7, 5, 3
    lanes = dr.arange(mi.UInt32, samples)
    fx, fy = ref_mod.film_position(mi, scene, mi.UInt32(x) + 0 * lanes, mi.UInt32(y) + 0 * lanes,
                                   lanes, samples, seed)
    rng = mi.PCG32()
    state, sequence = mi.sample_tea_32(mi.UInt32(seed), mi.UInt32(y * scene.width + x))
    rng.seed(initstate=mi.UInt64(state), initseq=mi.UInt64(sequence))
    expected = []
    for s in range(samples):
        jitter_x, jitter_y = rng.next_float32()[0], rng.next_float32()[0]
        expected.append((x + (s % side + jitter_x) / side, y + (s // side + jitter_y) / side))
    np.testing.assert_allclose(np.c_[np.asarray(fx), np.asarray(fy)], expected, rtol=0, atol=1e-6)
    assert (np.floor((np.asarray(fx) - x) * side) == np.arange(samples) % side).all()


@pytest.mark.parametrize("divisor", [1, 3, 49, 194, 2047, 16384, (1 << 18) - 1])
def test_a_lane_divides_as_integers_do(divisor):
    """The strips' rows come from a float64 reciprocal, not an integer division (LLVM divides
    lane by lane by an opaque divisor): floor(n / d) for every numerator below 2^18 and the
    multiples of d and their neighbours up to 2^32, as NumPy's integer division. Catches the
    half left out of (n + 0.5) / d (tried: 49 x q times the reciprocal of 49 rounds below q)."""
    mi = ref_mod.mitsuba_module("llvm_ad_rgb")
    multiples = np.arange(1, (1 << 32) // divisor, max(1, (1 << 32) // divisor // 4096),
                          dtype=np.uint64) * divisor
    numerators = np.unique(np.concatenate([
        np.arange(1 << 18, dtype=np.uint64), multiples, multiples - 1, multiples + 1]))
    numerators = numerators[numerators < 1 << 32].astype(np.uint32)
    got = np.asarray(ref_mod._divide(mi, mi.UInt32(numerators), divisor))
    np.testing.assert_array_equal(got, numerators // np.uint32(divisor))


def test_samples_must_be_square(scene_at):
    with pytest.raises(ValueError, match="square"):
        compute_reference(scene_at("box_plane", 32), samples=8)


def _cache_file(tmp_path):
    (path,) = (tmp_path / "reference").glob("*.npz")
    return path


@pytest.mark.parametrize("damage", ["zero_length", "truncated", "wrong_shape", "no_arrays"])
def test_a_damaged_cache_entry_is_traced_again(damage, scene_at, tmp_path, monkeypatch):
    """A cache file that cannot be read or holds another shape is a miss: traced again and
    replaced. Catches the old reader (seen failing): EOFError on a zero-length file on every
    rerun, a (2, 2) reference returned for a 40x40 scene, TypeError on an .npy named .npz
    (a truncated zip it already handled)."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path))
    scene = scene_at("box_plane", 40)
    first = compute_reference(scene, samples=4)
    path = _cache_file(tmp_path)
    match damage:
        case "zero_length":
            path.write_bytes(b"")
        case "truncated":
            path.write_bytes(path.read_bytes()[:100])
        case "wrong_shape":
            np.savez(path.with_suffix(""), visibility=np.ones((2, 2), np.float32),
                     covered=np.ones((2, 2), bool), direct=np.zeros(0, np.float32),
                     seconds=1.0, variant="llvm_ad_rgb")
        case "no_arrays":
            np.save(path.with_suffix(""), np.zeros(3))
            path.with_suffix(".npy").replace(path)
    again = compute_reference(scene, samples=4)
    assert not again.cached and again.visibility.shape == (40, 40)
    assert np.array_equal(again.visibility, first.visibility)
    assert compute_reference(scene, samples=4).cached  # the entry was replaced


def test_a_full_cache_warns_and_still_returns_the_reference(scene_at, tmp_path, monkeypatch):
    """Disk full while storing: one warning, the reference is returned, and no later call
    tries to write again. Catches the old code, whose ENOSPC aborted the sweep (seen failing)."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path))
    monkeypatch.setattr(ref_mod, "_cache_write_failure", None)
    attempts = []

    def disk_full(path, arrays, **options):
        attempts.append(path)
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(ref_mod, "write_entry", disk_full)
    with pytest.warns(RuntimeWarning, match="No space left on device"):
        ref = compute_reference(scene_at("box_plane", 32), samples=4)
    assert ref.visibility.shape == (32, 32) and not ref.cached
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert compute_reference(scene_at("box_plane", 36), samples=4).visibility.shape == (36, 36)
    assert len(attempts) == 1


def test_nan_geometry_is_an_untraceable_scene(scene_at):
    """A NaN vertex (e.g. a lathe profile with NaN) gives UntraceableSceneError naming the
    scene and the part. Catches a reference without the check (seen failing): the old code let
    Mitsuba's bare RuntimeError "attempted to gather from an empty array" out; the new kernel
    would silently return a reference with nothing covered."""
    scene = scene_at("box_plane", 16)
    part = scene.parts[1]
    vertices = part.vertices.copy()
    vertices[0, 2] = np.nan
    broken = dataclasses.replace(scene, parts=[scene.parts[0],
                                               dataclasses.replace(part, vertices=vertices)])
    with pytest.raises(UntraceableSceneError, match=f"'box_plane'.*NaN or Inf in vertices of "
                                                    f"{re.escape(part.name)}"):
        compute_reference(broken, samples=4, use_cache=False)


def test_a_mitsuba_failure_is_an_untraceable_scene(scene_at, monkeypatch):
    """Whatever Mitsuba raises while loading or tracing becomes UntraceableSceneError with
    Mitsuba's message on one line. Catches a compute_reference that lets Mitsuba's RuntimeError
    through (seen failing with the try/except removed)."""
    def unknown_plugin(scene, mi, samples, seed=0):
        return {"type": "scene", "thing": {"type": "no_such_plugin"}}

    monkeypatch.setattr(ref_mod, "mitsuba_scene_dict", unknown_plugin)
    with pytest.raises(UntraceableSceneError, match="'box_plane' cannot be traced: .*no_such_plugin"
                       ) as caught:
        compute_reference(scene_at("box_plane", 16), samples=4, use_cache=False)
    assert "\n" not in str(caught.value)
