"""The Mitsuba reference: exact hard-shadow visibility averaged over each pixel's area.

Per pixel, ``samples`` jittered stratified primary rays from the matched camera; from each hit
one shadow ray toward the spot or point light's position or against the directional light's
direction.
V_ref is the lit fraction of the samples that hit geometry. A pixel is covered when the ray
through its centre hits geometry, exactly the GL rasteriser's coverage rule. All of it is one
Dr.Jit kernel over the pixels, as Mitsuba's own integrators run (``scalar_rgb``: a pixel loop).
When the scene's effects include ``direct``, Mitsuba's ``direct`` integrator (delta light,
diffuse BSDFs, no indirect light) renders the shaded image too.
Results are cached on disk under a hash of the scene, resolution, samples and Mitsuba version,
with a checksum of their arrays; an entry that fails its checksum or the checks of V (finite, in
[0, 1], this scene's shape) is traced again, rewritten and noted for the manifest, and a cache
that cannot be written is skipped with a warning.
A scene Mitsuba cannot trace raises :class:`UntraceableSceneError`.
"""

from __future__ import annotations

import hashlib
import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import cache_root, square_number
from ..config.cache_entry import DamagedEntry, note_rebuilt, read_entry, write_entry
from ..scene import BuiltScene
from .mitsuba_scene import mitsuba_origin, mitsuba_scene_dict
from .variant import choose_variant, mitsuba_module
from .cutouts import (CUTOUT_VERSION, MAX_CUTOUT_HITS, cutout_ray_intersect)

CACHE_VERSION = 6  # bump when the reference's definition changes; 6: checksums


class UntraceableSceneError(RuntimeError):
    """Mitsuba cannot trace this scene (NaN or Inf in its geometry, camera or light, or an error
    Mitsuba raised loading or tracing it). The message is one line naming the scene."""


@dataclass
class Reference:
    visibility: np.ndarray  # float32 (H, W)
    covered: np.ndarray  # bool (H, W)
    direct: np.ndarray | None  # float32 (H, W, 3) direct-lit radiance, or None
    seconds: float  # ray-tracing time when computed (not the cache load), the build included
    variant: str
    cached: bool = False
    build_seconds: float = math.nan  # of it, building Mitsuba's scene (its BVH); NaN: not known
    # shadow rays stopped at MAX_CUTOUT_HITS cut-out hits (counted occluded) when traced; a
    # cached reference does not keep the count (-1)
    bounded_rays: int = -1


def cache_dir() -> Path:
    return cache_root() / "reference"


def _trace_samples(mi, mscene, scene: BuiltScene, x, y, s, samples: int, seed: int):
    """(hit, occluded, bounded) of sample ``s`` of pixel (x, y): the primary ray through its
    :func:`film_position` and the shadow ray from the hit (bounded: stopped at
    MAX_CUTOUT_HITS; always False in a scene without cut-outs).

    With a JIT variant ``x``, ``y`` and ``s`` are arrays, one lane per sample, and this is one
    Dr.Jit kernel, as Mitsuba's own ``mi.render`` lays out its wavefront; with ``scalar_rgb``
    they are ints and the same code runs as plain Python. Our scene-dependent values are opaque
    (Mitsuba's sensor still bakes in the film size), so Dr.Jit's kernel cache serves later
    scenes.
    """

    ray = _camera_ray(mi, mscene, scene, *film_position(mi, scene, x, y, s, samples, seed))
    if scene.has_alpha:  # the camera sees through cut-outs as the light does
        si, there, seen_bounded = _camera_hit(mi, mscene, scene, ray)
        hit = there | seen_bounded
        occluded, bounded = cutout_ray_test(mi, mscene, scene, _toward_light(mi, scene, si), hit)
        return hit, hit & occluded, hit & bounded
    # the shadow ray needs only the hit point and the face normal
    si = mscene.ray_intersect(ray, ray_flags=mi.RayFlags.Empty, coherent=True)
    hit = si.is_valid()
    shadow_ray = _toward_light(mi, scene, si)
    return hit, hit & mscene.ray_test(shadow_ray, coherent=True, active=hit), False


def _camera_hit(mi, mscene, scene: BuiltScene, ray):
    """:func:`cutout_ray_intersect` of a camera ray: on along the ray past each cut-out hit.
    A ray stopped at the bound sees the last cut-out it passed (not counted in
    Reference.bounded_rays, which counts shadow rays)."""
    return cutout_ray_intersect(mi, mscene, scene, ray, True,
                                lambda si, ray: si.spawn_ray(ray.d), coherent=True)


def _toward_light(mi, scene: BuiltScene, si):
    """The shadow ray from ``si``'s point, spawned past it (Mitsuba's offset along its
    normal: no hit on its own surface), toward the light: from a receiver, and again from
    each cut-out hit."""
    import drjit as dr

    light = scene.light
    if light.type == "directional":
        return si.spawn_ray(dr.opaque(mi.Vector3f, (-light.direction).tolist()))
    return si.spawn_ray_to(
        dr.opaque(mi.Point3f, (light.position - mitsuba_origin(scene)).tolist()))


def cutout_ray_test(mi, mscene, scene: BuiltScene, ray, active):
    """(occluded, bounded): whether the shadow ``ray`` meets a surface that is there under the
    scene's cut-outs, and whether it was stopped at the bound (occluded then too)."""
    _, there, bounded = cutout_ray_intersect(
        mi, mscene, scene, ray, active, lambda si, _: _toward_light(mi, scene, si))
    return there | bounded, bounded


def film_position(mi, scene: BuiltScene, x, y, s, samples: int, seed: int):
    """Film position (fx, fy), in pixels, of sample ``s`` of pixel (x, y): jittered in stratum
    ``s`` of a sqrt(samples) x sqrt(samples) grid by the numbers 2s and 2s + 1 of the pixel's
    PCG32 stream (seeded by a TEA hash of (seed, pixel index))."""
    import drjit as dr

    width = dr.opaque(mi.UInt32, scene.width)
    side = math.isqrt(samples)  # a literal, as trace_visibility's sample count
    rng = mi.PCG32()
    state, sequence = mi.sample_tea_32(dr.opaque(mi.UInt32, seed), y * width + x)
    rng.seed(initstate=mi.UInt64(state), initseq=mi.UInt64(sequence))
    if dr.is_jit_v(mi.Float):
        # rng += 2 s without the advance's loop (a loop in every lane: 8 % of the trace at
        # 512^2 on castle): the advanced state is mult * state + plus * inc, whose factors
        # depend on the distance alone, taken from a table of the pixel's sample distances
        mult, plus = _pcg_advance_table(samples)
        rng.state = (dr.gather(mi.UInt64, mi.UInt64(mult), s) * rng.state
                     + dr.gather(mi.UInt64, mi.UInt64(plus), s) * rng.inc)
    else:
        rng += mi.Int64(2 * s)
    jitter_x, jitter_y = rng.next_float32(), rng.next_float32()
    return (mi.Float(x) + (mi.Float(s % side) + jitter_x) / mi.Float(side),
            mi.Float(y) + (mi.Float(s // side) + jitter_y) / mi.Float(side))


def _camera_ray(mi, mscene, scene: BuiltScene, fx, fy):
    """The primary ray through film position (fx, fy) in pixels."""
    import drjit as dr

    width, height = dr.opaque(mi.UInt32, scene.width), dr.opaque(mi.UInt32, scene.height)
    ray, _ = mscene.sensors()[0].sample_ray(
        0.0, 0.5, mi.Point2f(fx / mi.Float(width), fy / mi.Float(height)), mi.Point2f(0.5, 0.5))
    return ray


PCG32_MULT = 0x5851F42D4C957F2D  # PCG32's LCG multiplier (O'Neill; Dr.Jit's random.h)
U64 = (1 << 64) - 1


def _pcg_advance_table(samples: int) -> tuple[list[int], list[int]]:
    """Per sample s, (mult, plus) with PCG32 advanced by 2 s from state S with increment I at
    mult S + plus I (mod 2^64): the advance's loop (Brown, "Random number generation with
    arbitrary strides", 1994, as PCG32's ``advance``) with its increment factored out, since
    every term it adds is a multiple of I."""
    mults, pluses = [], []
    for s in range(samples):
        delta, cur_mult, cur_plus, acc_mult, acc_plus = 2 * s, PCG32_MULT, 1, 1, 0
        while delta:
            if delta & 1:
                acc_mult, acc_plus = acc_mult * cur_mult & U64, (acc_plus * cur_mult + cur_plus) & U64
            cur_plus, cur_mult = (cur_mult + 1) * cur_plus & U64, cur_mult * cur_mult & U64
            delta >>= 1
        mults.append(acc_mult)
        pluses.append(acc_plus)
    return mults, pluses


def _covered(mi, mscene, scene: BuiltScene, x, y):
    """Whether the ray through the centre of pixel (x, y) hits geometry (where it is there,
    under the cut-outs): GL's coverage rule."""
    ray = _camera_ray(mi, mscene, scene, mi.Float(x) + 0.5, mi.Float(y) + 0.5)
    if scene.has_alpha:
        _, there, bounded = _camera_hit(mi, mscene, scene, ray)
        return there | bounded
    return mscene.ray_test(ray, coherent=True)


def _divide(mi, numerator, divisor: int):
    """numerator // divisor, per lane, for numerators below 2^32 and a divisor below 2^18, by
    the divisor's float64 reciprocal (opaque: one kernel serves every divisor): exact, since
    (n + 0.5) / d lies at least 0.5 / d from an integer and the product errs by less than
    2^-20. LLVM has no SIMD integer division: by an opaque divisor it divides lane by lane,
    which had made the reference's trace 10 % slower than Mitsuba's own integrator."""
    import drjit as dr

    reciprocal = dr.opaque(mi.Float64, 1.0 / divisor)
    return mi.UInt32(dr.floor((mi.Float64(numerator) + 0.5) * reciprocal))


def _strip_pixels(mi, lane, width: int, height: int):
    """(x, y) of each lane when lanes run down two-row strips (x0y0, x0y1, x1y0, ...): a SIMD
    packet of coverage rays then traces a 4x2 block of pixels rather than 8x1. An odd last row
    runs alone."""
    import drjit as dr

    strip = _divide(mi, lane, 2 * width)
    width, height = dr.opaque(mi.UInt32, width), dr.opaque(mi.UInt32, height)
    within = lane - strip * 2 * width
    paired = 2 * strip + 1 < height
    return dr.select(paired, within // 2, within), 2 * strip + dr.select(paired, within % 2, 0)


def _visibility(hits: np.ndarray, shadowed: np.ndarray) -> np.ndarray:
    """The lit fraction of the samples that hit geometry (float32); 1 where none hit."""
    lit = (hits - shadowed).astype(np.float32) / np.maximum(hits, 1).astype(np.float32)
    return np.where(hits > 0, lit, np.float32(1))


def trace_visibility(mi, mscene, scene: BuiltScene, samples: int, seed: int,
                     counts: dict | None = None):
    """(V, covered) as (H, W) arrays; ``counts["bounded_rays"]``, when ``counts`` is given:
    the shadow rays stopped at MAX_CUTOUT_HITS (0 without cut-outs).

    JIT variants: one lane per sample, a pixel's samples in adjacent lanes (a SIMD packet of
    primary rays then covers one pixel), each lane adding its hit and its occlusion to its
    pixel's tally in the same kernel (hits in the low 32 bits of a UInt64, occluded samples in
    the high ones), as Mitsuba's film adds its samples; then a lane per pixel for the coverage
    rays. ``scalar_rgb``: a loop over pixels and samples.
    """
    import drjit as dr

    w, h = scene.width, scene.height
    if dr.is_jit_v(mi.Float):
        lane = dr.arange(mi.UInt32, w * h * samples)
        count = samples  # a literal: Dr.Jit divides by it with a shift (a kernel per count)
        x, y = _strip_pixels(mi, lane // count, w, h)
        hit, occluded, bounded = _trace_samples(mi, mscene, scene, x, y, lane % count,
                                                samples, seed)
        tally = dr.zeros(mi.UInt64, w * h)
        stopped = dr.zeros(mi.UInt32, 1)
        if scene.has_alpha:
            dr.scatter_add(stopped, dr.select(bounded, mi.UInt32(1), 0), mi.UInt32(0),
                           mode=dr.ReduceMode.Local)
        # a pixel's samples share a SIMD packet: reduced in the packet, one atomic add each
        dr.scatter_add(tally, dr.select(hit, mi.UInt64(1), 0) +
                       dr.select(occluded, mi.UInt64(1 << 32), 0), y * dr.opaque(mi.UInt32, w) + x,
                       mode=dr.ReduceMode.Local)
        x, y = _strip_pixels(mi, dr.arange(mi.UInt32, w * h), w, h)
        covered = dr.empty(mi.Bool, w * h)
        dr.scatter(covered, _covered(mi, mscene, scene, x, y), y * dr.opaque(mi.UInt32, w) + x)
        dr.eval(tally, covered, stopped)
        if counts is not None:
            counts["bounded_rays"] = int(np.asarray(stopped)[0])
        tally = np.asarray(tally, np.uint64).reshape(h, w)
        return (_visibility(tally & 0xFFFFFFFF, tally >> np.uint64(32)),
                np.asarray(covered, bool).reshape(h, w))
    hits, shadowed, covered = (np.zeros((h, w), np.int64), np.zeros((h, w), np.int64),
                               np.empty((h, w), bool))
    stopped = 0
    for y in range(h):
        for x in range(w):
            for s in range(samples):
                hit, occluded, bounded = _trace_samples(mi, mscene, scene, x, y, s, samples,
                                                        seed)
                hits[y, x] += bool(hit)
                shadowed[y, x] += bool(occluded)
                stopped += bool(bounded)
            covered[y, x] = bool(_covered(mi, mscene, scene, x, y))
    if counts is not None:
        counts["bounded_rays"] = stopped
    return _visibility(hits, shadowed), covered


def cache_key(scene: BuiltScene, samples: int, seed: int) -> str:
    import mitsuba as mi

    text = f"{scene.key}|{scene.width}x{scene.height}|{samples}|{seed}|{mi.__version__}|" \
           f"{CACHE_VERSION}|{'direct' in scene.config.effects}"
    if scene.has_alpha:  # the textures' bytes (a mesh file's own, a family's) and the loop's
        text += f"|cutouts {CUTOUT_VERSION} {MAX_CUTOUT_HITS}|" + "|".join(
            m.digest for m in scene.alpha_masks)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


REFERENCE_ENTRY = {"visibility": ("f", 2), "covered": ("b", 2), "direct": ("f", None),
                   "seconds": ("f", 0), "variant": ("U", 0), "build_seconds": ("f", 0)}


def _read_cached(path: Path, scene: BuiltScene) -> Reference | None:
    """The cached reference at ``path``, verified: its checksum (:mod:`harness.config.
    cache_entry`), then this scene's shape and dtypes, V finite and in [0, 1], the direct image
    finite and not negative; None when there is no entry. A DamagedEntry when a check fails."""
    z = read_entry(path, REFERENCE_ENTRY)
    if z is None:
        return None
    visibility, covered, direct = z["visibility"], z["covered"], z["direct"]
    shape = (scene.height, scene.width)
    wants_direct = "direct" in scene.config.effects
    if (visibility.shape != shape or visibility.dtype != np.float32 or covered.shape != shape
            or direct.dtype != np.float32
            or direct.shape != (shape + (3,) if wants_direct else (0,))):
        raise DamagedEntry(f"not this scene's {scene.width}x{scene.height} arrays")
    if not ((visibility >= 0) & (visibility <= 1)).all():  # NaN fails it too
        raise DamagedEntry("visibility not in [0, 1]")
    if not (direct >= 0).all() or not np.isfinite(direct).all():
        raise DamagedEntry("direct image not finite and >= 0")
    seconds = float(z["seconds"])
    if not seconds >= 0:
        raise DamagedEntry("seconds not >= 0")
    return Reference(visibility, covered, direct if wants_direct else None, seconds,
                     str(z["variant"]), cached=True, build_seconds=float(z["build_seconds"]))


_cache_write_failure: str | None = None  # why this process stopped writing the cache


def _write_cache(path: Path, ref: Reference) -> None:
    """Store ``ref``; a cache that cannot be written (disk full, read-only) is switched off for
    this process with one warning, and the reference is still returned."""
    global _cache_write_failure
    if _cache_write_failure is not None:
        return
    try:
        # processes sharing the cache (Dask workers) may trace one scene at once: each writes
        # its own temporary file
        write_entry(path, {
            "visibility": ref.visibility, "covered": ref.covered,
            "direct": ref.direct if ref.direct is not None else np.zeros(0, np.float32),
            "seconds": np.float64(ref.seconds), "variant": np.array(ref.variant),
            "build_seconds": np.float64(ref.build_seconds)}, compressed=True)
    except OSError as e:
        _cache_write_failure = f"{path.parent}: {e.strerror or e}"
        warnings.warn(f"reference cache not writable ({_cache_write_failure}); references are "
                      "no longer cached in this process", RuntimeWarning, stacklevel=3)


def _check_finite(scene: BuiltScene) -> None:
    cam, light = scene.config.camera, scene.light
    values = {f"vertices of {part.name}": part.vertices for part in scene.parts}
    values.update({"camera": np.r_[cam.position, cam.target, cam.up, cam.yfov, cam.near, cam.far],
                   "light": np.r_[() if light.direction is None else light.direction,
                                  () if light.position is None else light.position]})
    bad = [name for name, v in values.items() if not np.isfinite(v).all()]
    if bad:
        raise UntraceableSceneError(f"scene {scene.name!r} cannot be traced: NaN or Inf in "
                                    f"{', '.join(bad)}")


def compute_reference(scene: BuiltScene, *, samples: int = 16, seed: int = 0,
                      variant: str | None = None, use_cache: bool = True) -> Reference:
    """V_ref, coverage (and the direct image) of ``scene``, from the cache when present.

    Raises :class:`UntraceableSceneError` for a scene Mitsuba cannot trace."""
    square_number(samples)
    path = cache_dir() / f"{cache_key(scene, samples, seed)}.npz"
    damaged = None
    try:
        cached = _read_cached(path, scene) if use_cache else None
    except DamagedEntry as e:
        cached, damaged = None, str(e)
    if cached is not None:
        return cached
    _check_finite(scene)
    variant = variant or choose_variant()
    mi = mitsuba_module(variant)
    start = time.perf_counter()
    try:
        mscene = mi.load_dict(mitsuba_scene_dict(scene, mi, samples, seed))
        built = time.perf_counter() - start
        counts: dict = {}
        visibility, covered = trace_visibility(mi, mscene, scene, samples, seed, counts)
        direct = None
        if "direct" in scene.config.effects:
            direct = np.asarray(mi.render(mscene, spp=samples, seed=seed), np.float32)[..., :3]
    except RuntimeError as e:  # what Mitsuba and Dr.Jit raise for a scene they cannot handle
        cause = " ".join(str(e).split()) or type(e).__name__
        raise UntraceableSceneError(f"scene {scene.name!r} cannot be traced: {cause}") from e
    ref = Reference(visibility, covered, direct, time.perf_counter() - start, variant,
                    build_seconds=built, bounded_rays=counts["bounded_rays"])
    if ref.bounded_rays:
        warnings.warn(f"scene {scene.name!r}: {ref.bounded_rays} shadow rays passed "
                      f"{MAX_CUTOUT_HITS} cut-out hits and were counted occluded",
                      RuntimeWarning, stacklevel=2)
    if use_cache:
        _write_cache(path, ref)
        if damaged:
            note_rebuilt(path, damaged)
    return ref
