"""The report's images: visibility, signed error, shaded images and diagnostic maps as palette
images (one byte a pixel: 255 colours for values and one for "none"), the worst edge window of a
run, data URIs at the size shown and PNG files at native size.

An image here is an array of values with NaN where there is nothing to show, and a
:class:`Scale` that colours it. Colours (the viewer's legend repeats them): V grey from dark
(shadow) to white (lit), pixels the view does not cover blue-grey; error white where V agrees
with the reference, red where V is lit and the reference shadowed, blue the reverse, light grey
where nothing is compared."""

from __future__ import annotations

import base64
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from ..truth import metrics
from ..results import replace_atomically

SHOWN_PX = 256  # the longer side of an image as the page shows it
STEPS = 255  # palette entries for values; entry 255 is "none"


@dataclass(frozen=True)
class Scale:
    """Values from ``lo`` to ``hi`` onto ``palette[0..254]``, NaN onto ``palette[255]``."""

    palette: np.ndarray  # (256, 3) uint8
    lo: float = 0.0
    hi: float = 1.0

    def index(self, values: np.ndarray) -> np.ndarray:
        t = (np.asarray(values, np.float32) - self.lo) * ((STEPS - 1) / max(self.hi - self.lo, 1e-12))
        missing = np.isnan(t)
        out = np.rint(np.clip(np.where(missing, 0, t), 0, STEPS - 1)).astype(np.uint8)
        out[missing] = STEPS
        return out


def _palette(colours: np.ndarray, none: tuple[int, int, int]) -> np.ndarray:
    return np.vstack([np.round(np.clip(colours, 0, 1) * 255), [none]]).astype(np.uint8)


_T = np.linspace(0, 1, STEPS)[:, None]
NOT_COVERED, NOT_COMPARED = (89, 115, 153), (217, 217, 217)
VISIBILITY = Scale(_palette(0.15 + 0.85 * np.repeat(_T, 3, 1), NOT_COVERED))
SHADED = Scale(_palette(np.repeat(_T, 3, 1) ** (1 / 2.2), NOT_COVERED))
# -1 (blue: shadow where the reference is lit) .. 0 (white) .. +1 (red: lit where it is shadowed)
_E = 2 * _T - 1
ERROR = Scale(_palette(np.hstack([1 - np.clip(-_E, 0, 1), 1 - np.abs(_E), 1 - np.clip(_E, 0, 1)]),
                       NOT_COMPARED), lo=-1.0, hi=1.0)
LEGEND = {
    "visibility": [("#262626", "shadow (V = 0)"), ("#ffffff", "lit (V = 1)"),
                   ("#597399", "not covered by the view")],
    "error": [("#ffffff", "agrees with the reference"),
              ("#ff0000", "lit where the reference is in shadow"),
              ("#0000ff", "in shadow where the reference is lit"),
              ("#d9d9d9", "not compared (not covered, facing away from the light, outside "
                          "a spot's cone)")],
}


def viridis(lo: float, hi: float) -> Scale:
    from plotly.colors import sample_colorscale, unlabel_rgb

    colours = sample_colorscale("Viridis", list(np.linspace(0, 1, STEPS)))
    return Scale(_palette(np.array([unlabel_rgb(c) for c in colours]) / 255.0, NOT_COMPARED),
                 lo, hi)


def visibility(v: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """V where the view covers a pixel (a NaN of the technique's shown as 0.5), NaN elsewhere."""
    return np.where(covered, np.nan_to_num(np.asarray(v, np.float64), nan=0.5), np.nan)


def signed_error(v: np.ndarray, ref: np.ndarray, compared: np.ndarray) -> np.ndarray:
    """V - V_ref in [-1, 1] where compared, NaN elsewhere."""
    d = np.clip(np.nan_to_num(np.asarray(v, np.float64), nan=0.5) - ref, -1, 1)
    return np.where(compared, d, np.nan)


def map_scale(values: np.ndarray) -> Scale:
    """Viridis between a map's 1st and 99th percentiles (NaN: none)."""
    finite = values[np.isfinite(values)]
    lo, hi = np.percentile(finite, [1, 99]) if finite.size else (np.nan, np.nan)
    return viridis(float(lo), float(hi))


def edge_crop(ref: np.ndarray, covered: np.ndarray) -> tuple[int, int, int] | None:
    """(row, col, size) of the square window holding the most reference shadow-edge pixels,
    or None when the reference has no shadow edge (see :func:`worst_window`)."""
    band = metrics.edge_band(ref, mask=covered)
    return worst_window(band.astype(np.float64)) if band.any() else None


def worst_edge_crop(d: np.ndarray, ref: np.ndarray, compared: np.ndarray
                    ) -> tuple[int, int, int] | None:
    """(row, col, size) of the window where the run's |V - V_ref| summed over the reference's
    edge band is largest; the most edge pixels where the run makes no edge error; None without
    a shadow edge."""
    band = metrics.edge_band(ref, mask=compared)
    if not band.any():
        return None
    weight = np.where(band, np.abs(np.nan_to_num(d)), 0.0)
    return worst_window(weight if weight.any() else band.astype(np.float64))


def worst_window(weight: np.ndarray) -> tuple[int, int, int]:
    """(row, col, size) of the square window of largest total ``weight``. The window is an
    eighth of the shorter side (at least 24 px): small enough that stair-stepping shows when
    enlarged."""
    from scipy import ndimage

    h, w = weight.shape
    size = min(h, w, max(24, min(h, w) // 8))
    sums = ndimage.uniform_filter(weight, size=size, mode="constant")
    half = size // 2
    inner = sums[half:h - size + half + 1, half:w - size + half + 1]  # windows inside the image
    r, c = np.unravel_index(np.argmax(inner), inner.shape)
    return int(r), int(c), size


def crop(values: np.ndarray, window: tuple[int, int, int]) -> np.ndarray:
    r, c, size = window
    return values[r:r + size, c:c + size]


def shrink_factor(width: int, height: int, px: int | None = None) -> int:
    """The whole factor that brings an image's longer side to ``px`` (SHOWN_PX) or below."""
    return max(1, -(-max(width, height) // (px or SHOWN_PX)))


def _blocks(values: np.ndarray, f: int) -> np.ndarray:
    """(h', w', f*f) blocks of f x f pixels, NaN-padded at the right and bottom."""
    h, w = values.shape
    sh, sw = -(-h // f), -(-w // f)
    padded = np.full((sh * f, sw * f), np.nan)
    padded[:h, :w] = values
    return padded.reshape(sh, f, sw, f).transpose(0, 2, 1, 3).reshape(sh, sw, f * f)


def shrink_mean(values: np.ndarray, px: int | None = None) -> np.ndarray:
    """Down to ``px`` (SHOWN_PX) by averaging each block's values (a fractional V stays
    fractional); NaN where a block has none."""
    f = shrink_factor(values.shape[1], values.shape[0], px)
    if f == 1:
        return values
    blocks = _blocks(values, f)
    count = np.isfinite(blocks).sum(-1)
    total = np.nansum(blocks, -1)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def shrink_error(d: np.ndarray, px: int | None = None) -> np.ndarray:
    """Signed error down to ``px`` (SHOWN_PX) keeping each block's largest |error|, so a
    one-pixel error of a 1024-pixel image still shows as one pixel at 256."""
    f = shrink_factor(d.shape[1], d.shape[0], px)
    if f == 1:
        return d
    blocks = _blocks(d, f)
    magnitude = np.where(np.isnan(blocks), -1.0, np.abs(blocks))
    return np.take_along_axis(blocks, magnitude.argmax(-1)[..., None], -1)[..., 0]


def _image(values: np.ndarray, scale: Scale) -> Image.Image:
    image = Image.fromarray(scale.index(values), mode="P")
    image.putpalette(scale.palette.tobytes())
    return image


def data_uri(values: np.ndarray, scale: Scale) -> str:
    """The image as a data URI: lossless WebP (about half the size of a palette PNG here), at
    the encoder's low effort: half the time of its default (method 4, quality 80), 5 % larger."""
    out = io.BytesIO()
    _image(values, scale).convert("RGB").save(out, format="WEBP", lossless=True, method=1,
                                              quality=0)
    return "data:image/webp;base64," + base64.b64encode(out.getvalue()).decode("ascii")


def write_png(values: np.ndarray, scale: Scale, path: Path) -> None:
    """A palette PNG at native size, written whole (:func:`harness.results.replace_atomically`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    replace_atomically(path, lambda f: _image(values, scale).save(f, format="PNG", compress_level=1))
