"""How a map's texels compare with the camera's pixels on the receivers: the
``texels_per_pixel`` columns every map technique reports (a diagnostic, untimed, float64)."""

from __future__ import annotations

import hashlib
import weakref
from collections import OrderedDict
from typing import Callable, Sequence

import numpy as np

from harness.technique import Frame
from harness.truth.metrics import receives_light

from .light_maps import CubeDepthMap, LightDepthMap, camera_rays


def texel_over_pixel(frame: Frame, view_proj: np.ndarray, res: float,
                     mask: np.ndarray | None = None) -> np.ndarray:
    """Per pixel of ``mask`` (the ``receivers``' where None; row-major order), the side of the
    map texel it reads over the side of the pixel, both taken on the receiver's plane:
    1 / sqrt|det J|, J the 2 x 2 derivative of the map's texel position along the plane by
    window position (the map texel's area over the pixel's footprint's, square-rooted: below 1
    the map has finer texels than the view's pixels, above 1 coarser). ``view_proj`` the
    map's world -> clip matrix, ``res`` its texels per side."""
    along = _receiver_plane(frame, receivers(frame) if mask is None else mask)
    return _ratio(along, np.asarray(view_proj, np.float64), float(res))


def _receiver_plane(frame: Frame, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(point, d point / d x, d point / d y) of each pixel of ``mask``, in float64: the window
    derivatives along the receiver's plane (the ray's hit moves with the ray). What every map
    a pixel might read shares."""
    a = frame.arrays
    point = a.position[mask].astype(np.float64)
    normal = a.normal[mask].astype(np.float64)
    rows, cols = np.nonzero(mask)
    rays = camera_rays(frame)
    x = cols + 0.5
    y = frame.height - 1 - rows + 0.5
    ray = rays["camera_ray"] + x[:, None] * rays["camera_ray_dx"] + y[:, None] * rays["camera_ray_dy"]
    facing = np.einsum("nk,nk->n", normal, ray)
    t = np.einsum("nk,nk->n", normal, point - rays["camera_position"]) / facing
    along = [t[:, None] * (d - ((normal @ d) / facing)[:, None] * ray)
             for d in (rays["camera_ray_dx"], rays["camera_ray_dy"])]
    return point, along[0], along[1]


def _ratio(plane: tuple[np.ndarray, np.ndarray, np.ndarray], view_proj: np.ndarray,
           res: float) -> np.ndarray:
    point, along_x, along_y = plane
    clip = point @ view_proj[:, :3].T + view_proj[:, 3]
    scale = 0.5 * res / clip[:, 3]
    # d (texel x, texel y) / d point: the perspective division's derivative, row by row
    rows_xy = [(view_proj[i, :3] - (clip[:, i] / clip[:, 3])[:, None] * view_proj[3, :3])
               * scale[:, None] for i in (0, 1)]
    j = [[np.einsum("nk,nk->n", r, d) for d in (along_x, along_y)] for r in rows_xy]
    det = j[0][0] * j[1][1] - j[0][1] * j[1][0]
    with np.errstate(divide="ignore", invalid="ignore"):
        return 1.0 / np.sqrt(np.abs(det))


def receivers(frame: Frame) -> np.ndarray:
    """The pixels the light reaches (harness.truth.metrics.receives_light) that the view covers."""
    a = frame.arrays
    return a.covered & receives_light(a.normal, a.position, frame.scene.light,
                                      frame.camera.position)


def texels_per_pixel(frame: Frame, maps: Sequence[tuple[np.ndarray, float]],
                     choice: np.ndarray | Callable[[], np.ndarray] | None = None, *,
                     choice_key: bytes = b"") -> dict:
    """The ``texels_per_pixel_median`` and ``texels_per_pixel_p95`` columns over the receivers
    (texel_over_pixel): ``maps`` the (world -> clip matrix, texels per side) of each map the
    technique reads, ``choice`` (H, W) the map index each pixel reads (all the first where
    None; a pixel with a negative index is left out), or a function giving it, called only
    when the columns are not at hand, with ``choice_key`` naming what it depends on besides
    the maps and the camera pass. None where no pixel counts.

    Computed once for a camera pass, light, set of maps and choice (0.05 to 0.15 s at
    512 x 512, as long as sm's frame): the frames of a run, and of the runs an interleaved
    batch takes turns with, find their columns among the last ``RECENT``."""
    matrices = np.array([m for m, _ in maps], np.float64)
    sizes = np.array([r for _, r in maps], np.float64)
    light = frame.scene.light
    if callable(choice):
        named = choice_key
    else:
        named = b"" if choice is None else np.ascontiguousarray(choice).tobytes()
    key = (id(frame.arrays), hashlib.sha256(b"".join(
        np.ascontiguousarray(a, np.float64).tobytes() for a in (
            matrices, sizes, light.direction if light.direction is not None else (),
            light.position if light.position is not None else ())) + named).digest())
    found = _recent.get(key)
    if found is not None and found[0]() is frame.arrays:
        _recent.move_to_end(key)
        return dict(found[1])
    columns = _texels_per_pixel(frame, matrices, sizes, choice() if callable(choice) else choice)
    _recent[key] = (weakref.ref(frame.arrays), columns)
    while len(_recent) > RECENT:
        _recent.popitem(last=False)
    return dict(columns)


# (camera pass, maps) -> (the pass's arrays, weakly: a released frame's go; its columns). A
# sweep's interleaved batch holds up to 16 runs, each its own maps; the last entry alone
# (before) was another run's at every frame: make bench spent 30 % of its time here
RECENT = 64
_recent: OrderedDict = OrderedDict()


def texel_ratios(frame: Frame, maps: Sequence[tuple[np.ndarray, float]],
                 choice: np.ndarray | None = None) -> np.ndarray:
    """texel_over_pixel of every receiver in the map it reads (``maps`` and ``choice`` as
    texels_per_pixel's), the finite ones: what the two columns summarise."""
    return _texel_ratios(frame, np.array([m for m, _ in maps], np.float64),
                         np.array([r for _, r in maps], np.float64), choice)


def _receivers_on_their_plane(frame: Frame) -> tuple[np.ndarray, tuple]:
    """(receivers, their _receiver_plane) of the frame's camera pass and light: the same for
    every map a run or a batch's runs read there (two thirds of a column's cost where each
    set of maps computed them again)."""
    light = frame.scene.light
    key = (id(frame.arrays), b"".join(
        np.ascontiguousarray(v, np.float64).tobytes() if v is not None else b"-"
        for v in (light.direction, light.position)))
    found = _planes.get(key)
    if found is not None and found[0]() is frame.arrays:
        return found[1]
    mask = receivers(frame)
    _planes.clear()  # one camera pass at a time: a batch's runs share each frame's
    # dropped with the pass's arrays: a 1024^2 view's plane is 75 MB
    _planes[key] = (weakref.ref(frame.arrays, lambda _: _planes.pop(key, None)),
                    (mask, _receiver_plane(frame, mask)))
    return _planes[key][1]


_planes: dict = {}  # (camera pass, light) -> (the pass's arrays, weakly; receivers and plane)


def _texel_ratios(frame: Frame, matrices: np.ndarray, sizes: np.ndarray,
                  choice: np.ndarray | None) -> np.ndarray:
    mask, (point, along_x, along_y) = _receivers_on_their_plane(frame)
    if choice is None:  # every receiver reads the one map: no picking (copies of the plane)
        ratio = _ratio((point, along_x, along_y), matrices[0], sizes[0])
        return ratio[np.isfinite(ratio)]
    index = choice[mask].astype(np.int64)
    ratio = np.full(len(index), np.nan)
    for k in np.unique(index[index >= 0]):  # one map at a time: each its own matrix
        pick = index == k
        ratio[pick] = _ratio((point[pick], along_x[pick], along_y[pick]), matrices[k], sizes[k])
    return ratio[np.isfinite(ratio)]


def _texels_per_pixel(frame: Frame, matrices: np.ndarray, sizes: np.ndarray,
                      choice: np.ndarray | None) -> dict:
    ratio = _texel_ratios(frame, matrices, sizes, choice)
    if not ratio.size:
        return {"texels_per_pixel_median": None, "texels_per_pixel_p95": None}
    return {"texels_per_pixel_median": float(np.median(ratio)),
            "texels_per_pixel_p95": float(np.percentile(ratio, 95))}


def light_map_texels_per_pixel(frame: Frame, light_map: LightDepthMap | CubeDepthMap) -> dict:
    """texels_per_pixel of one light depth map: its frustum, or a point light's cube, each
    pixel reading the face its direction from the light falls in (CUBE_AXES' order)."""
    if isinstance(light_map, LightDepthMap):
        return texels_per_pixel(frame, [(light_map.frustum.view_proj, light_map.res)])
    away = frame.arrays.position.astype(np.float64) - frame.scene.light.position
    axis = np.abs(away).argmax(axis=-1)
    face = 2 * axis + (np.take_along_axis(away, axis[..., None], -1)[..., 0] < 0)
    return texels_per_pixel(frame, [(f.view_proj, light_map.size) for f in light_map.faces],
                            face)
