"""The Mitsuba reference: exact hard-shadow visibility averaged over each pixel's area.

Per pixel, ``samples`` jittered stratified primary rays from the matched camera; from each hit
one shadow ray toward the spot light's position or against the directional light's direction.
V_ref is the lit fraction of the samples that hit geometry. A pixel is covered when the ray
through its centre hits geometry, exactly the GL rasteriser's coverage rule. When the scene's
effects include ``direct``, Mitsuba's ``direct`` integrator (delta light, diffuse BSDFs, no
indirect light) renders the shaded image too.
Results are cached on disk under a hash of the scene, resolution, samples and Mitsuba version.
"""

from __future__ import annotations

import glob
import hashlib
import math
import os
import re
import time
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import square_number
from .results import save_arrays
from .scene import BuiltScene

CACHE_VERSION = 4  # bump when the reference's definition changes
LLVM_SEARCH = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64",
               "/usr/lib", "/usr/local/lib")
# Irradiance (directional) or intensity (spot) of pi makes the diffuse radiance albedo * cos
# (/ r^2 for the spot), the same scale the GL side shades with.
LIGHT_POWER = math.pi


@dataclass
class Reference:
    visibility: np.ndarray  # float32 (H, W)
    covered: np.ndarray  # bool (H, W)
    direct: np.ndarray | None  # float32 (H, W, 3) direct-lit radiance, or None
    seconds: float  # ray-tracing time when computed (not the cache load)
    variant: str
    cached: bool = False


def cache_dir() -> Path:
    root = os.environ.get("SHADOWBENCH_CACHE") or Path.home() / ".cache" / "shadowbench"
    return Path(root) / "reference"


def _llvm_libraries() -> list[tuple[int, str]]:
    found = []
    for folder in LLVM_SEARCH:
        for path in glob.glob(os.path.join(folder, "libLLVM*.so*")):
            m = re.search(r"libLLVM-?(\d+)", os.path.basename(path))
            if m:
                found.append((int(m.group(1)), path))
    return sorted(found, reverse=True)


def choose_variant() -> str:
    """Pick a Mitsuba variant without loading one that would abort the process.

    ``cuda_ad_rgb`` when Dr.Jit finds a CUDA device; else ``llvm_ad_rgb`` when an LLVM >= 16
    library exists (Dr.Jit's LLVM backend aborts, uncatchably, with LLVM 15 or older), and
    Dr.Jit is pointed at it; else ``scalar_rgb`` with a warning.
    ``$SHADOWBENCH_MITSUBA_VARIANT`` forces a variant.
    """
    import drjit as dr
    import mitsuba as mi

    forced = os.environ.get("SHADOWBENCH_MITSUBA_VARIANT")
    if forced:
        return forced
    if "cuda_ad_rgb" in mi.variants() and dr.has_backend(dr.JitBackend.CUDA):
        return "cuda_ad_rgb"
    chosen = os.environ.get("DRJIT_LIBLLVM_PATH")
    libraries = _llvm_libraries()
    if not chosen and libraries and libraries[0][0] >= 16:
        os.environ["DRJIT_LIBLLVM_PATH"] = chosen = libraries[0][1]
    version = next((v for v, p in libraries if p == chosen), None)
    if chosen and (version is None or version >= 16) and "llvm_ad_rgb" in mi.variants():
        return "llvm_ad_rgb"
    warnings.warn(
        "no LLVM >= 16 found (Debian: apt-get install libllvm19); the reference falls back to "
        "Mitsuba's scalar_rgb variant, which is much slower", RuntimeWarning, stacklevel=2)
    return "scalar_rgb"


def _mitsuba(variant: str):
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


def _mesh(mi, name: str, vertices: np.ndarray, faces: np.ndarray, albedo: float):
    mesh = mi.Mesh(name, len(vertices), len(faces), has_vertex_normals=False)
    params = mi.traverse(mesh)
    # the buffers' own types: mi.Float in the JIT variants, dynamic arrays in scalar ones
    for key, array in (("vertex_positions", np.asarray(vertices, np.float32)),
                       ("faces", np.asarray(faces, np.uint32))):
        params[key] = type(params[key])(np.ascontiguousarray(array).ravel())
    params.update()
    mesh.set_bsdf(mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb",
                                                                   "value": [albedo] * 3}}))
    return mesh


def mitsuba_origin(scene: BuiltScene) -> np.ndarray:
    """Where Mitsuba's world origin sits in scene coordinates: the centre of the bounds.

    Mitsuba traces in float32 and offsets shadow rays by an epsilon relative to the magnitude
    of the coordinates; around 1e5 that offset reaches a scene unit and shadows go missing.
    Visibility is translation invariant, so the reference traces the scene moved next to the
    origin (the same float32 vertices, shifted in float64 exactly).
    """
    return np.round(scene.bounds.mean(axis=0))


def mitsuba_scene_dict(scene: BuiltScene, mi, samples: int, seed: int = 0) -> dict:
    """The scene for Mitsuba: the same meshes, the matched camera, the delta light,
    translated by ``-mitsuba_origin(scene)``."""
    cam = scene.config.camera
    origin = mitsuba_origin(scene)
    d: dict = {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": cam.yfov,
            "near_clip": cam.near,
            "far_clip": cam.far,
            "to_world": mi.ScalarTransform4f().look_at(
                origin=(np.asarray(cam.position) - origin).tolist(),
                target=(np.asarray(cam.target) - origin).tolist(), up=cam.up),
            "film": {"type": "hdrfilm", "width": scene.width, "height": scene.height,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "stratified", "sample_count": samples, "seed": seed},
        },
    }
    light = scene.light
    if light.type == "directional":
        d["light"] = {"type": "directional", "direction": light.direction.tolist(),
                      "irradiance": {"type": "rgb", "value": [LIGHT_POWER] * 3}}
    else:
        half = light.fov_deg / 2
        d["light"] = {
            "type": "spot", "cutoff_angle": half, "beam_width": half,
            "intensity": {"type": "rgb", "value": [LIGHT_POWER * light.power_scale] * 3},
            "to_world": mi.ScalarTransform4f().look_at(
                origin=(light.position - origin).tolist(),
                target=(light.position - origin + light.direction).tolist(),
                up=_up_for(light.direction).tolist()),
        }
    for i, part in enumerate(scene.parts):
        vertices = part.vertices.astype(np.float64) - origin
        d[f"mesh{i}"] = _mesh(mi, f"mesh{i}", vertices, part.faces, part.albedo)
    return d


def _up_for(direction: np.ndarray) -> np.ndarray:
    from .transforms import any_perpendicular_up

    return any_perpendicular_up(direction)


def _sample_positions(width: int, height: int, samples: int, rows: slice, seed: int):
    """Jittered stratified film positions in [0,1]^2 for the rows in ``rows``: (N, 2)."""
    side = math.isqrt(samples)
    rng = np.random.default_rng([seed, rows.start])
    ys, xs, sy, sx = np.meshgrid(np.arange(rows.start, rows.stop), np.arange(width),
                                 np.arange(side), np.arange(side), indexing="ij")
    jitter = rng.random((2,) + xs.shape)
    px = (xs + (sx + jitter[0]) / side) / width
    py = (ys + (sy + jitter[1]) / side) / height
    return np.stack([px.ravel(), py.ravel()], axis=1).astype(np.float32)


def _shadow_ray(mi, si, scene: BuiltScene):
    light = scene.light
    if light.type == "directional":
        return si.spawn_ray(mi.Vector3f(*(-light.direction).tolist()))
    return si.spawn_ray_to(mi.Point3f(*(light.position - mitsuba_origin(scene)).tolist()))


def _trace_visibility(mi, mscene, scene: BuiltScene, positions: np.ndarray):
    """(hit, lit) booleans for the film positions, with Mitsuba's vectorised ray queries."""
    sensor = mscene.sensors()[0]
    n = len(positions)
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(positions[:, 0], positions[:, 1]),
                               mi.Point2f(np.full(n, 0.5, np.float32),
                                          np.full(n, 0.5, np.float32)))
    si = mscene.ray_intersect(ray)
    hit = si.is_valid()
    occluded = mscene.ray_test(_shadow_ray(mi, si, scene), hit)
    return np.asarray(hit, dtype=bool), np.asarray(hit & ~occluded, dtype=bool)


def _trace_visibility_scalar(mi, mscene, scene: BuiltScene, positions: np.ndarray):
    sensor = mscene.sensors()[0]
    hit = np.zeros(len(positions), bool)
    lit = np.zeros(len(positions), bool)
    for i, (x, y) in enumerate(positions):
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(x, y), mi.Point2f(0.5, 0.5))
        si = mscene.ray_intersect(ray)
        if not si.is_valid():
            continue
        hit[i] = True
        lit[i] = not mscene.ray_test(_shadow_ray(mi, si, scene))
    return hit, lit


def cache_key(scene: BuiltScene, samples: int, seed: int) -> str:
    import mitsuba as mi

    text = f"{scene.key}|{scene.width}x{scene.height}|{samples}|{seed}|{mi.__version__}|" \
           f"{CACHE_VERSION}|{'direct' in scene.config.effects}"
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def compute_reference(scene: BuiltScene, *, samples: int = 16, seed: int = 0,
                      variant: str | None = None, use_cache: bool = True,
                      rays_per_batch: int = 1 << 22) -> Reference:
    square_number(samples)
    path = cache_dir() / f"{cache_key(scene, samples, seed)}.npz"
    if use_cache and path.is_file():
        try:
            with np.load(path) as z:
                direct = z["direct"] if z["direct"].size else None
                return Reference(z["visibility"], z["covered"], direct, float(z["seconds"]),
                                 str(z["variant"]), cached=True)
        except (OSError, ValueError, KeyError, zipfile.BadZipFile):
            pass  # an unreadable cache entry is a miss: trace again and replace it
    variant = variant or choose_variant()
    mi = _mitsuba(variant)
    start = time.perf_counter()
    mscene = mi.load_dict(mitsuba_scene_dict(scene, mi, samples, seed))
    w, h = scene.width, scene.height
    rows_per_batch = max(1, rays_per_batch // (w * samples))
    hits, lits = [], []
    trace = _trace_visibility if variant != "scalar_rgb" else _trace_visibility_scalar
    for y0 in range(0, h, rows_per_batch):
        rows = slice(y0, min(h, y0 + rows_per_batch))
        hit, lit = trace(mi, mscene, scene, _sample_positions(w, h, samples, rows, seed))
        hits.append(hit.reshape(-1, samples))
        lits.append(lit.reshape(-1, samples))
    hit_count = np.concatenate(hits).sum(1).reshape(h, w)
    lit_count = np.concatenate(lits).sum(1).reshape(h, w)
    ys, xs = np.mgrid[0:h, 0:w]
    centres = np.stack([(xs.ravel() + 0.5) / w, (ys.ravel() + 0.5) / h], 1).astype(np.float32)
    covered = trace(mi, mscene, scene, centres)[0].reshape(h, w)
    visibility = np.where(hit_count > 0, lit_count / np.maximum(hit_count, 1), 1.0)
    direct = None
    if "direct" in scene.config.effects:
        direct = np.asarray(mi.render(mscene, spp=samples, seed=seed), np.float32)[..., :3]
    ref = Reference(visibility.astype(np.float32), covered, direct,
                    time.perf_counter() - start, variant)
    if use_cache:
        # processes sharing the cache (Dask workers) may trace one scene at once
        save_arrays(path, visibility=ref.visibility, covered=ref.covered,
                    direct=direct if direct is not None else np.zeros(0, np.float32),
                    seconds=ref.seconds, variant=variant)
    return ref
