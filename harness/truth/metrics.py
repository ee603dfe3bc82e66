"""Error metrics between a technique's visibility V and the reference V_ref.

Small pure functions in the style of ``skimage.metrics``: arrays first, options as keywords,
shapes checked. ``mask`` selects the pixels compared (covered in both views); ``None`` means all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

EDGE_WIDTH = 2  # pixels either side of a reference shadow boundary
# part of every run id: a change to what the metrics compare makes stored results stale
VERSION = 3


def _check(v: np.ndarray, ref: np.ndarray, mask: np.ndarray | None):
    v, ref = np.asarray(v, dtype=np.float64), np.asarray(ref, dtype=np.float64)
    if v.ndim != 2 or v.shape != ref.shape:
        raise ValueError(f"expected two 2-D arrays of one shape, got {v.shape} and {ref.shape}")
    return v, ref, _check_mask(mask, v.shape)


def _check_mask(mask, shape, name: str = "mask") -> np.ndarray:
    if mask is None:
        return np.ones(shape, bool)
    mask = np.asarray(mask)
    if mask.shape != shape or mask.dtype != bool:
        raise ValueError(f"{name} must be bool of shape {shape}, got {mask.dtype} {mask.shape}")
    return mask


def _mean(values: np.ndarray) -> float:
    return float(values.mean()) if values.size else float("nan")


def mae(v, ref, *, mask=None) -> float:
    """Mean absolute difference over the masked pixels."""
    v, ref, mask = _check(v, ref, mask)
    return _mean(np.abs(v - ref)[mask])


def rmse(v, ref, *, mask=None) -> float:
    v, ref, mask = _check(v, ref, mask)
    d = (v - ref)[mask]
    return float(np.sqrt((d * d).mean())) if d.size else float("nan")


def wrong_pct(v, ref, *, mask=None, threshold: float = 0.5) -> float:
    """Percent of masked pixels where |V - V_ref| exceeds ``threshold``."""
    v, ref, mask = _check(v, ref, mask)
    d = np.abs(v - ref)[mask]
    return float(100.0 * (d > threshold).mean()) if d.size else float("nan")


def shadow_boundary(ref, *, mask=None) -> np.ndarray:
    """Pixels on a reference shadow boundary: fractional V_ref, or a 4-neighbour (also in the
    mask) whose V_ref differs by at least 0.5."""
    ref = np.asarray(ref, dtype=np.float64)
    _, ref, mask = _check(ref, ref, mask)
    boundary = mask & (ref > 0) & (ref < 1)
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(1, None), slice(None, -1)
        jump = (np.abs(ref[tuple(a)] - ref[tuple(b)]) >= 0.5) & mask[tuple(a)] & mask[tuple(b)]
        boundary[tuple(a)] |= jump
        boundary[tuple(b)] |= jump
    return boundary


def edge_band(ref, *, mask=None, width: int = EDGE_WIDTH) -> np.ndarray:
    """Masked pixels within ``width`` pixels (Chebyshev distance) of a reference boundary."""
    _, _, mask = _check(ref, ref, mask)
    boundary = shadow_boundary(ref, mask=mask)
    if width > 0:
        boundary = ndimage.binary_dilation(boundary, structure=np.ones((3, 3), bool),
                                           iterations=width)
    return boundary & mask


def _band(ref, mask, width: int, band) -> np.ndarray:
    """``band`` (an :func:`edge_band` of ``ref`` already computed: runs scored against one
    reference share it), checked, or the edge band computed now."""
    if band is None:
        return edge_band(ref, mask=mask, width=width)
    band = np.asarray(band)
    if band.shape != ref.shape or band.dtype != bool:
        raise ValueError(f"band must be bool of shape {ref.shape}, got {band.dtype} {band.shape}")
    return band


def edge_mae(v, ref, *, mask=None, width: int = EDGE_WIDTH, band=None) -> float:
    """Mean |V - V_ref| within ``width`` pixels of a reference shadow boundary (``band``: that
    edge band, precomputed)."""
    v, ref, mask = _check(v, ref, mask)
    return _mean(np.abs(v - ref)[_band(ref, mask, width, band)])


def _outside_band_pct(wrong: np.ndarray, ref: np.ndarray, mask: np.ndarray, width: int,
                      band) -> float:
    """Percent of the masked pixels that are ``wrong`` and lie outside the edge band."""
    if not mask.any():
        return float("nan")
    counted = wrong & mask & ~_band(ref, mask, width, band)
    return float(100.0 * counted.sum() / mask.sum())


def acne_pct(v, ref, *, mask=None, width: int = EDGE_WIDTH, threshold: float = 0.98,
             band=None) -> float:
    """False shadow on lit surfaces: percent of the masked pixels that the reference sees fully
    lit (V_ref == 1), that lie outside the edge band, and where V < ``threshold``.

    The denominator is every masked (compared) pixel, not the lit ones, so ``acne_pct`` and
    ``leak_pct`` add up to the share of all compared pixels wrong away from shadow edges."""
    v, ref, mask = _check(v, ref, mask)
    return _outside_band_pct((ref == 1.0) & (v < threshold), ref, mask, width, band)


def leak_pct(v, ref, *, mask=None, width: int = EDGE_WIDTH, threshold: float = 0.02,
             band=None) -> float:
    """Light through occluders: percent of the masked pixels that the reference sees fully
    shadowed (V_ref == 0), that lie outside the edge band, and where V > ``threshold``.

    Like :func:`acne_pct`, the denominator is every masked (compared) pixel."""
    v, ref, mask = _check(v, ref, mask)
    return _outside_band_pct((ref == 0.0) & (v > threshold), ref, mask, width, band)


def edge_floor(ref, *, mask=None, width: int = EDGE_WIDTH, band=None) -> float:
    """The best ``edge_mae`` a technique answering only 0 or 1 can reach on this reference: the
    ``edge_mae`` of the reference rounded to 0/1 against itself (ties at 0.5 cost 0.5 either
    way)."""
    _, ref, mask = _check(ref, ref, mask)
    return edge_mae(np.rint(ref), ref, mask=mask, width=width, band=band)


def levels(v, ref, *, mask=None, width: int = EDGE_WIDTH, decimals: int = 5, band=None) -> int:
    """Number of distinct V values (rounded to ``decimals``) inside the edge band (``band``:
    precomputed)."""
    v, ref, mask = _check(v, ref, mask)
    return int(np.unique(np.round(v[_band(ref, mask, width, band)], decimals)).size)


def ssim(v, ref, *, mask=None, win_size: int = 7) -> float:
    """Mean structural similarity (scikit-image, data_range 1) over the masked pixels.

    Like scikit-image's own mean, a border of win_size // 2 pixels is left out.
    """
    from skimage.metrics import structural_similarity

    v, ref, mask = _check(v, ref, mask)
    _, full = structural_similarity(ref, v, data_range=1.0, full=True, win_size=win_size)
    pad = win_size // 2
    inner = np.zeros_like(mask)
    inner[pad:-pad, pad:-pad] = mask[pad:-pad, pad:-pad]
    return _mean(full[inner])


def psnr(v, ref, *, mask=None) -> float:
    """Peak signal-to-noise ratio (scikit-image, data_range 1) of the masked pixels."""
    from skimage.metrics import peak_signal_noise_ratio

    v, ref, mask = _check(v, ref, mask)
    if not mask.any():
        return float("nan")
    if np.array_equal(ref[mask], v[mask]):  # what scikit-image returns, without its warning
        return float("inf")
    return float(peak_signal_noise_ratio(ref[mask], v[mask], data_range=1.0))


def flip(image, reference_image, *, pixels_per_degree: float = 67.0) -> float:
    """Mean NVIDIA FLIP error of two LDR images (H, W, 3) with values in [0, 1], linear RGB."""
    import flip_evaluator

    image = np.asarray(image, dtype=np.float32)
    reference_image = np.asarray(reference_image, dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3 or image.shape != reference_image.shape:
        raise ValueError(f"expected two (H, W, 3) images, got {image.shape} and "
                         f"{reference_image.shape}")
    _, mean, _ = flip_evaluator.evaluate(
        np.clip(reference_image, 0, 1), np.clip(image, 0, 1), "LDR", inputsRGB=False,
        applyMagma=False, parameters={"ppd": pixels_per_degree})
    return float(mean)


def flicker(v, v_previous, ref, ref_previous, *, mask=None, mask_previous=None) -> float:
    """Mean |(V - V_previous) - (V_ref - V_ref_previous)| over the pixels compared in both
    frames (``mask`` and ``mask_previous``): the change between two frames of a sequence that
    the truth does not make. A technique wrong by the same amount in both frames scores 0;
    crawling edges and pops score high."""
    v, ref, mask = _check(v, ref, mask)
    v_previous, ref_previous, mask_previous = _check(v_previous, ref_previous, mask_previous)
    if v.shape != v_previous.shape:
        raise ValueError(f"frames of different shapes: {v.shape} and {v_previous.shape}")
    change = (v - v_previous) - (ref - ref_previous)
    return _mean(np.abs(change)[mask & mask_previous])


# A reprojected point is on the surface frame t-1 saw there when its 1/depth matches frame
# t-1's, interpolated bilinearly between the pixels around it, within this fraction. 1/depth
# is linear in screen space on a plane, so on one flat face the two agree but for float32
# rounding of the G-buffer (about 1e-6), and across a crease of a tessellated curve by a second-
# order term (a sphere of 4 subdivisions at 256 pixels: about 2e-4); an occluder in front of
# what is behind it differs by far more than 0.1% of its distance.
DEPTH_TOLERANCE = 1e-3
# a reprojected point within this many pixels of a pixel centre is at that centre: the float32
# G-buffer positions put an exact one-pixel move 1e-4 pixels off at 256 pixels
CENTRE_SNAP_PX = 1e-3


def view_depth(position, view_proj) -> np.ndarray:
    """Clip-space w of world points ``position`` (..., 3) under ``view_proj``: for a
    perspective camera (the harness's), their distance in front of it along its axis. The depth
    :func:`world_flicker` compares."""
    return _clip_row(np.asarray(position, dtype=np.float64),
                     np.asarray(view_proj, dtype=np.float64), 3)


def _clip_row(points: np.ndarray, view_proj: np.ndarray, row: int) -> np.ndarray:
    # by columns, not a matrix product: BLAS threads cost more than the sums on small arrays
    m = view_proj[row]
    return points[..., 0] * m[0] + points[..., 1] * m[1] + points[..., 2] * m[2] + m[3]


@dataclass(frozen=True)
class WorldPoints:
    """The pixels of frame t whose world point frame t-1 saw (:func:`world_points`), and for
    each the flat indices into t-1's image of the four pixel centres around it (repeated where
    the point is on a row or column of centres)."""

    pixels: np.ndarray  # (H, W) bool
    corners: tuple  # four int arrays, one index per pixel of ``pixels``


def world_points(position, view_proj_previous, depth_previous, *, mask=None,
                 mask_previous=None, depth_tolerance: float = DEPTH_TOLERANCE) -> WorldPoints:
    """Frame t's compared pixels (``mask``) taken to frame t-1, for :func:`world_flicker`: each
    pixel's world point (``position``, frame t's G-buffer, (H, W, 3)) projected with t-1's
    ``view_proj_previous``. A pixel is kept where its point lands in front of the camera and
    inside the image, the 1, 2 or 4 pixels whose centres surround it were compared in t-1
    (``mask_previous``), and its depth matches t-1's there (``depth_previous``, t-1's
    :func:`view_depth`; 1/depth interpolated between them, within ``depth_tolerance``: the
    same surface, not one t-1 saw in front of it). One computation serves every run scored on
    the same two frames.

    A pixel whose surface moved (a moving object) is another world point in t-1: the depth test
    drops most of them, not one sliding along itself; ``mask`` should leave those out."""
    position = np.asarray(position, dtype=np.float64)
    view_proj_previous = np.asarray(view_proj_previous, dtype=np.float64)
    depth_previous = np.asarray(depth_previous, dtype=np.float64)
    if position.ndim != 3 or position.shape[2] != 3:
        raise ValueError(f"position must be of shape (H, W, 3), got {position.shape}")
    shape = position.shape[:2]
    if view_proj_previous.shape != (4, 4):
        raise ValueError(f"view_proj_previous must be 4x4, got {view_proj_previous.shape}")
    if depth_previous.shape != shape:
        raise ValueError(f"depth_previous must be of shape {shape}, got {depth_previous.shape}")
    mask = _check_mask(mask, shape)
    mask_previous = _check_mask(mask_previous, shape, "mask_previous")
    height, width = shape
    points = position[mask]
    w = _clip_row(points, view_proj_previous, 3)
    in_front = w > 0
    safe_w = np.where(in_front, w, 1.0)
    # continuous pixel coordinates, centres at integers, row 0 at the top
    x = (_clip_row(points, view_proj_previous, 0) / safe_w + 1) / 2 * width - 0.5
    y = (1 - _clip_row(points, view_proj_previous, 1) / safe_w) / 2 * height - 0.5
    x = np.where(np.abs(x - np.rint(x)) < CENTRE_SNAP_PX, np.rint(x), x)
    y = np.where(np.abs(y - np.rint(y)) < CENTRE_SNAP_PX, np.rint(y), y)
    inside = in_front & (x >= 0) & (x <= width - 1) & (y >= 0) & (y <= height - 1)
    x, y = np.where(inside, x, 0.0), np.where(inside, y, 0.0)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.ceil(x).astype(np.int64), np.ceil(y).astype(np.int64)
    corners = [y0 * width + x0, y0 * width + x1, y1 * width + x0, y1 * width + x1]
    fx, fy = x - x0, y - y0
    weights = [(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy]
    seen = mask_previous.ravel()
    inverse_depth = 1.0 / np.where(seen, np.maximum(depth_previous.ravel(), 1e-300), 1.0)
    kept = inside.copy()
    for corner in corners:
        kept &= seen[corner]
    expected = sum(wt * inverse_depth[c] for wt, c in zip(weights, corners))
    kept &= np.abs(expected * safe_w - 1) <= depth_tolerance
    pixels = np.zeros(mask.shape, bool)
    pixels[mask] = kept
    return WorldPoints(pixels, tuple(c[kept] for c in corners))


def _world_change(now, previous, points: WorldPoints) -> np.ndarray:
    """How far each value of ``now`` at ``points.pixels`` lies outside the range of
    ``previous`` at the centres around its world point (signed; 0 inside): on a point exactly
    at a pixel centre p', now - previous(p')."""
    now, previous = _check(now, previous, None)[:2]
    if now.shape != points.pixels.shape:
        raise ValueError(f"frames of shape {now.shape} for world points of "
                         f"{points.pixels.shape}")
    now = now[points.pixels]
    around = np.stack([previous.ravel()[c] for c in points.corners])
    return now - np.clip(now, around.min(axis=0), around.max(axis=0))


def world_flicker(v, v_previous, ref, ref_previous, *, points: WorldPoints) -> float:
    """:func:`flicker` at fixed world points: shimmer, the change a technique makes where the
    surface stays put, apart from the image moving over it. ``points``: :func:`world_points`
    of the two frames.

    At each kept pixel p of frame t the change is how far V_t(p) lies outside the range of
    V_t-1 at the pixels whose centres surround p's world point in t-1 (1 at a centre, 2 on a
    line of centres, else 4); the truth's likewise; the value is the mean |change -
    change_ref|. On a point at a pixel centre p' that is |(V_t(p) - V_t-1(p')) - (V_ref,t(p)
    - V_ref,t-1(p'))|.

    Why the range and not one pixel: the point lands between pixel centres (up to half a pixel
    from the nearest), so the nearest pixel is another world point, and a still 0/1 edge
    between the two reads as a change: the resampling pixel flicker measures. A bilinear blend
    of the surrounding V invents fractions a 0/1 technique never answers, and calls every
    still hard edge flickering. The range calls still V still (a value between the surrounding
    ones is consistent with it) and keeps 0/1; its cost is that a change within a pixel of an
    edge hides."""
    change = _world_change(v, v_previous, points)
    change_ref = _world_change(ref, ref_previous, points)
    return _mean(np.abs(change - change_ref))


def world_changed_pct(v, v_previous, *, points: WorldPoints, threshold: float = 0.0) -> float:
    """Percent of the pixels :func:`world_flicker` compares (``points``) where V changed at
    the world point by more than ``threshold`` (lies that far outside the range around it in
    t-1), whatever the truth did: under a still light, the share of the view that shimmers."""
    change = _world_change(v, v_previous, points)
    return float(100.0 * (np.abs(change) > threshold).mean()) if change.size else float("nan")


POP_FACTOR = 5.0  # a frame flickering this many times the sequence's median pops


def pop_frames(flicker_series, *, factor: float = POP_FACTOR) -> int:
    """Frames whose :func:`flicker` exceeds ``factor`` times the median over the sequence's
    frames (NaN, a frame with no pixel compared in both, is left out): discontinuities such
    as a warp changing its basis."""
    series = np.asarray(flicker_series, dtype=np.float64)
    if series.ndim != 1:
        raise ValueError(f"expected a 1-D series, got shape {series.shape}")
    series = series[~np.isnan(series)]
    if not series.size:
        return 0
    return int(np.count_nonzero(series > factor * np.median(series)))


def nonfinite(*arrays) -> int:
    """Count of NaN and Inf values across the arrays."""
    return int(sum(np.count_nonzero(~np.isfinite(np.asarray(a, dtype=np.float64)))
                   for a in arrays))


def receives_light(normal, position, light, camera_position) -> np.ndarray:
    """Pixels the light can reach: the visible side faces the light (n . l > 0, with n turned
    toward the camera) and, for a spot light, the point lies inside its cone (a point light
    has none: it reaches every surface facing it).

    Elsewhere a surface receives no direct light whatever V says, and techniques
    legitimately differ there (shadow volumes shadow a back face, a biased map may call it
    lit; a spot's map calls everything outside its cone lit), so visibility is compared only
    where the light arrives. ``light`` is a :class:`harness.scene.Light`.
    """
    normal = np.asarray(normal, dtype=np.float64)
    position = np.asarray(position, dtype=np.float64)
    if normal.shape != position.shape or normal.shape[-1:] != (3,):
        raise ValueError(f"expected normal and position of one (..., 3) shape, got "
                         f"{normal.shape} and {position.shape}")
    toward_camera = np.sign((normal * (np.asarray(camera_position) - position)).sum(-1))
    reached = (normal * light.to_light(position)).sum(-1) * toward_camera > 0
    if light.type == "spot":
        reached &= light.inside_cone(position)
    return reached


def shade(visibility, normal, position, albedo, light, *, ambient: float) -> np.ndarray:
    """GL-side shaded image: albedo * (ambient + V * direct Lambert), as RGB (H, W, 3).

    The direct term matches the reference's light power: cos for a directional light,
    cos * power_scale / r^2 for a point light and inside the cone for a spot light (``light``
    is a :class:`harness.scene.Light`).
    """
    to_light = light.to_light(position)
    cos = np.clip((normal * to_light).sum(-1), 0, None)
    if light.positional:
        d = position - light.position
        cos = cos * light.power_scale / np.maximum((d * d).sum(-1), 1e-12)
    if light.type == "spot":
        cos = np.where(light.inside_cone(position), cos, 0.0)
    value = albedo * (ambient + np.asarray(visibility) * cos)
    return np.repeat(value[..., None], 3, axis=2).astype(np.float32)
