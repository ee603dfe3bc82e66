"""How a fitted warp serves the visible receivers: where points land in its map, which fall
outside it, and the screen size of one map texel (the aliasing) per pixel and in summary.
"""

from __future__ import annotations

import numpy as np

# The aliasing statistics count surfaces with n . l above this (about 87 degrees from the light):
# a face parallel to the light has an infinite texel footprint, and the projection factor
# 1 / (n . l) of the faces counted stays below 20.
ALIAS_MIN_COS = 0.05
# alias_near: the nearest part of the visible depth range, where the papers argue for the warps.
NEAR_FRACTION = 0.2


def map_coordinates(clip: np.ndarray, points: np.ndarray, res: int) -> tuple[np.ndarray, np.ndarray]:
    """Map texel coordinates (..., 2) and clip w (...) of world points (..., 3)."""
    c = np.einsum("ij,...j->...i", clip, np.concatenate([points, np.ones(points.shape[:-1] + (1,))], -1))
    with np.errstate(divide="ignore", invalid="ignore"):
        texel = (c[..., :2] / c[..., 3:] * 0.5 + 0.5) * res
    return texel, c


def outside_unit_cube(clip: np.ndarray, position: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Covered pixels whose world position falls outside the map's unit cube (or behind it)."""
    _, c = map_coordinates(clip, position, 1)
    w = c[..., 3]
    tolerance = 1e-5 * np.abs(w)
    inside = (w > 0) & np.all(np.abs(c[..., :3]) <= w[..., None] + tolerance[..., None], axis=-1)
    return covered & ~inside


def alias_map(clip: np.ndarray, res: int, position: np.ndarray, normal: np.ndarray,
              covered: np.ndarray) -> np.ndarray:
    """Per pixel, the largest screen extent of one map texel, in pixels (1 = a texel per pixel).

    From numpy finite differences of the map coordinates of the G-buffer world positions: J is
    d(texel)/d(pixel) from the right and lower neighbours, and a texel spans 1 / sigma_min(J)
    pixels. Pixels whose neighbours are not on their own plane (silhouettes, creases) get NaN.
    """
    texel, _ = map_coordinates(clip, position.astype(np.float64), res)
    h, w = covered.shape
    alias = np.full((h, w), np.nan)
    p, n = position.astype(np.float64), normal.astype(np.float64)
    centre, right, down = p[:-1, :-1], p[:-1, 1:], p[1:, :-1]
    scale = np.linalg.norm(right - centre, axis=-1) + np.linalg.norm(down - centre, axis=-1) + 1e-12
    on_plane = ((np.abs(np.einsum("...i,...i", right - centre, n[:-1, :-1])) < 1e-3 * scale)
                & (np.abs(np.einsum("...i,...i", down - centre, n[:-1, :-1])) < 1e-3 * scale))
    valid = covered[:-1, :-1] & covered[:-1, 1:] & covered[1:, :-1] & on_plane
    dx = texel[:-1, 1:] - texel[:-1, :-1]
    dy = texel[1:, :-1] - texel[:-1, :-1]
    jac = np.stack([dx, dy], axis=-1)  # (..., texel axis, pixel axis)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        sigma_min = smallest_singular_value(np.where(np.isfinite(jac), jac, 0.0))
        alias[:-1, :-1] = np.where(valid & np.all(np.isfinite(jac), axis=(-1, -2)),
                                   1.0 / sigma_min, np.nan)
    return alias


def smallest_singular_value(m: np.ndarray) -> np.ndarray:
    """The smaller singular value of each 2 x 2 matrix of ``m`` (..., 2, 2), in closed form:
    numpy's batched SVD took 0.4 s for a 512 x 512 image's Jacobians. With t = |M|_F^2 and
    d = det M, sigma_min^2 = 2 d^2 / (t + sqrt(t^2 - 4 d^2)), which does not cancel."""
    t = np.einsum("...ij,...ij->...", m, m)
    d = m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
    root = np.sqrt(np.maximum(t * t - 4 * d * d, 0.0))
    return np.where(t > 0, np.abs(d) * np.sqrt(2 / np.where(t > 0, t + root, 1.0)), 0.0)


def alias_statistics(alias: np.ndarray, normal: np.ndarray, position: np.ndarray,
                     covered: np.ndarray, light, camera_view: np.ndarray) -> dict:
    """``alias_mean`` and ``alias_max`` of an :func:`alias_map` over the covered surfaces facing
    the light (n . l > ALIAS_MIN_COS, n turned toward the camera; inside a spot light's cone),
    and ``alias_near``, its mean over those of them within the nearest NEAR_FRACTION of the
    visible view-depth range. NaN where no pixel counts."""
    camera = -camera_view[:3, :3].T @ camera_view[:3, 3]
    n = normal.astype(np.float64)
    toward_camera = np.sign((n * (camera - position)).sum(-1))
    facing = covered & ((n * light.to_light(position)).sum(-1) * toward_camera > ALIAS_MIN_COS)
    if light.type == "spot":
        facing &= light.inside_cone(position)
    depth = -(position @ camera_view[2, :3] + camera_view[2, 3])
    near = np.zeros_like(covered)
    if covered.any():
        lo, hi = depth[covered].min(), depth[covered].max()
        near = depth <= lo + NEAR_FRACTION * (hi - lo)

    def stat(reduce, mask):
        values = alias[mask]
        values = values[~np.isnan(values)]
        return float(reduce(values)) if values.size else float("nan")

    return dict(alias_mean=stat(np.mean, facing), alias_max=stat(np.max, facing),
                alias_near=stat(np.mean, facing & near))
