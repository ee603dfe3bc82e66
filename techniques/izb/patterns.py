"""Where a pixel's view samples sit: offsets from the pixel's centre, in pixels, x right and
y up (GL's window coordinates).

``rotated``: one fixed pattern for every pixel. One sample is the pixel's centre (rt's ray
origin); four are the rotated grid of RGSS (a 4 x 4 grid's cells on two diagonals of a 2:1
slope); 8, 16 and 32 a rank-1 lattice, the rotated (sheared) grid generalised: sample i at
x = (i + 1/2) / n, y = frac((g i + 1/2) / n), one sample in each row and each column, with the
generator g of largest smallest distance between samples (the pixel wrapped around).
``reference``: per pixel, the sub-pixel positions of the reference's own primary rays
(:func:`harness.truth.reference.film_position`: its stratified jitter, seed 0), so that V
compares with the reference sample by sample.
"""

from __future__ import annotations

import math

import numpy as np

RGSS = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])


def _wrapped_distance(points: np.ndarray) -> float:
    d = np.abs(points[:, None] - points[None])
    d = np.minimum(d, 1 - d)
    distance = np.sqrt((d ** 2).sum(-1))
    return float(distance[~np.eye(len(points), dtype=bool)].min())


def lattice(n: int) -> np.ndarray:
    """The rank-1 lattice of ``n`` points in the unit square with the largest smallest
    distance (the first such generator)."""
    i = np.arange(n)
    best = None
    for g in range(1, n):
        if math.gcd(g, n) != 1:
            continue
        points = np.column_stack([(i + 0.5) / n, ((g * i + 0.5) / n) % 1.0])
        if best is None or _wrapped_distance(points) > _wrapped_distance(best):
            best = points
    return best


def rotated(samples: int) -> np.ndarray:
    """(samples, 2) float32 offsets from the pixel's centre."""
    if samples == 1:
        return np.zeros((1, 2), np.float32)
    unit = RGSS if samples == 4 else lattice(samples)
    return (unit - 0.5).astype(np.float32)


def reference(scene, samples: int, seed: int = 0) -> np.ndarray:
    """(H * W * samples, 2) float32 offsets: the reference's film positions of every pixel's
    samples, pixel (x, y) of GL's rows (row 0 at the bottom) at slot (y W + x) samples + k."""
    from harness.truth import reference as truth

    mi = truth.mitsuba_module(truth.choose_variant())
    w, h = scene.width, scene.height
    lane = np.arange(w * h * samples, dtype=np.uint32)
    pixel, k = lane // samples, lane % samples
    x, gl_row = pixel % w, pixel // w
    top_row = h - 1 - gl_row
    fx, fy = truth.film_position(mi, scene, mi.UInt32(x), mi.UInt32(top_row), mi.UInt32(k),
                                 samples, seed)
    fx, fy = np.asarray(fx, np.float64), np.asarray(fy, np.float64)
    # film y grows downwards from the top row; GL's window y upwards from the bottom
    return np.column_stack([fx - (x + 0.5), (top_row + 0.5) - fy]).astype(np.float32)
