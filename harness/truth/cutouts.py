"""Cut-outs in the reference (issue 48): rays that go on past the hits where a surface is cut
out, one bounded Dr.Jit loop for shadow, camera and coverage rays (harness.truth.reference uses
it), and the sampling rule of harness/scene/alpha.py ported to Dr.Jit."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import BuiltScene

# Cut-outs (issue 48). Mitsuba's ray_test treats every surface as opaque; in a scene with
# alpha-tested surfaces a shadow ray, a camera ray and a coverage ray go on past each hit
# where the sampling rule (harness/scene/alpha.py) says the surface is cut out, and stop at
# the first hit where it is there. At most MAX_CUTOUT_HITS cut-out hits are passed: a shadow
# ray that passes that many is counted as occluded (and counted: Reference.bounded_rays), a
# camera ray sees the last.
CUTOUT_ATTRIBUTE = "face_cutout"
MAX_CUTOUT_HITS = 64
CUTOUT_VERSION = 2  # bump when the cut-out loop's definition changes (opaque scenes: no key);
# 2: camera and coverage rays go on past cut-outs too


def jit_variant(mi) -> bool:
    """Whether ``mi`` is a JIT (LLVM or CUDA) variant of Mitsuba, not scalar_rgb."""
    import drjit as dr

    return dr.is_jit_v(mi.Float)


def cutout_ray_intersect(mi, mscene, scene: BuiltScene, ray, active, onward,
                         coherent: bool = False):
    """(si, there, bounded): ``ray``'s first hit where the surface is there under the scene's
    cut-outs, going on past each cut-out hit ``si`` along ``onward(si, ray)``; ``bounded``
    where it passed MAX_CUTOUT_HITS cut-outs (``si`` then the last of them). A bounded Dr.Jit
    loop of ray_intersect (``scalar_rgb``: a Python loop, the rule in NumPy, ``si`` None for
    an inactive ray). Shadow rays and camera rays alike."""
    import drjit as dr

    flags = mi.RayFlags.Minimal | mi.RayFlags.UV
    if not jit_variant(mi):
        si = None
        for _ in range(MAX_CUTOUT_HITS if active else 0):
            si = mscene.ray_intersect(ray, flags, False)
            if not si.is_valid():
                return si, False, False
            mask = int(si.shape.eval_attribute_1(CUTOUT_ATTRIBUTE, si))
            if mask < 0 or scene.alpha_masks[mask].opaque(np.array([si.uv.x, si.uv.y])):
                return si, True, False
            ray = onward(si, ray)
        return si, False, bool(active)
    table = cutout_table(mi, scene)

    def going(ray, active, si, there, passed):
        return active

    def step(ray, active, si, there, passed):
        found_si = mscene.ray_intersect(ray, flags, coherent, active)
        found = active & found_si.is_valid()
        si = dr.select(found, found_si, si)
        mask = mi.Int32(si.shape.eval_attribute_1(CUTOUT_ATTRIBUTE, si, found))
        cut = found & (mask >= 0)
        is_there = found & (~cut | surface_there(mi, table, mask, si.uv, cut))
        passed = dr.select(cut & ~is_there, passed + 1, passed)
        active = cut & ~is_there & (passed < MAX_CUTOUT_HITS)
        return (onward(si, ray), active, si, there | is_there, passed)

    width = dr.width(active)
    _, _, si, there, passed = dr.while_loop(
        (ray, mi.Bool(active), dr.zeros(mi.SurfaceInteraction3f, width),
         dr.zeros(mi.Bool, width), dr.zeros(mi.UInt32, width)), going, step,
        label="cutout_ray_intersect")
    return si, there, ~there & (passed >= MAX_CUTOUT_HITS)


@dataclass
class CutoutTable:
    """The scene's cut-out textures for Dr.Jit: per texel of every mask, one after another,
    its value and those of its right, lower and lower-right neighbours (repeat wrap), one byte
    each (0..255) in a UInt32, so that a bilinear sample is one gather (four were 55 % of the
    trace of a card); and per mask its first texel, width, height and cutoff."""

    quads: object
    first: object
    width: object
    height: object
    cutoff: object


def cutout_table(mi, scene: BuiltScene) -> CutoutTable:
    masks = scene.alpha_masks
    sizes = [m.texture.size for m in masks]

    def per_mask(values, kind, dtype):
        # two entries at least (a copy of the last): Dr.Jit reads a one-entry array as a scalar
        # load whose IR carries the allocation's alignment, so each trace of a one-mask scene
        # was a new kernel (0.12 s of LLVM at 512 x 512, half of a card's trace)
        return kind(np.array(values + values[-1:] * (len(values) < 2), dtype))

    return CutoutTable(
        mi.UInt32(np.concatenate([_texel_quads(m.texture).ravel() for m in masks])),
        per_mask(np.cumsum([0] + sizes[:-1]).tolist(), mi.UInt32, np.uint32),
        per_mask([m.texture.shape[1] for m in masks], mi.Float64, np.float64),
        per_mask([m.texture.shape[0] for m in masks], mi.Float64, np.float64),
        per_mask([m.cutoff for m in masks], mi.Float64, np.float64))


def _texel_quads(texture: np.ndarray) -> np.ndarray:
    """(H, W) uint32: each texel's byte, then its right, lower and lower-right neighbours'
    (wrapped) in the next bytes up."""
    t = texture.astype(np.uint32)
    right = np.roll(t, -1, axis=1)
    return t | right << 8 | np.roll(t, -1, axis=0) << 16 | np.roll(right, -1, axis=0) << 24


def surface_there(mi, table: CutoutTable, mask, uv, active):
    """The sampling rule (harness/scene/alpha.py's sample_alpha, step for step in float64):
    whether the cut-out ``mask`` is there (alpha >= cutoff) at ``uv``."""
    import drjit as dr

    index = mi.UInt32(dr.maximum(mask, 0))
    w = dr.gather(mi.Float64, table.width, index, active)
    h = dr.gather(mi.Float64, table.height, index, active)
    x = mi.Float64(uv.x) * w - 0.5
    y = mi.Float64(uv.y) * h - 0.5
    x0, y0 = dr.floor(x), dr.floor(y)
    fx, fy = x - x0, y - y0
    at = (dr.gather(mi.UInt32, table.first, index, active)
          + mi.UInt32(_wrapped(y0, h)) * mi.UInt32(w) + mi.UInt32(_wrapped(x0, w)))
    quad = dr.gather(mi.UInt32, table.quads, at, active)

    def texel(byte):
        return mi.Float64((quad >> (8 * byte)) & 0xFF) / 255.0

    top = texel(0) * (1 - fx) + texel(1) * fx
    bottom = texel(2) * (1 - fx) + texel(3) * fx
    return top * (1 - fy) + bottom * fy >= dr.gather(mi.Float64, table.cutoff, index, active)


def _wrapped(i, n):
    """``i`` mod ``n`` in [0, n) for whole float64 numbers (NumPy's np.mod)."""
    import drjit as dr

    r = i - dr.floor(i / n) * n
    return dr.select(r >= n, r - n, dr.select(r < 0, r + n, r))
