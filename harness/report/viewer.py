"""The image viewer's data: for every run of a scene, its V, signed error, shaded image (scenes
with ``effects: [direct]``), the worst edge window cropped from reference, V and error, and the
technique's own maps, as data URIs at the size shown; files at native size under
``images/<scene>/<W>x<H>/`` where the page shows an image smaller than it is."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import images as im
from . import plots
from .stored import Folder, slug


class SceneImages:
    """Images of one scene, reference by image size, runs by their place in the run list."""

    def __init__(self, folder: Folder, scene: str, shown_px: int = im.SHOWN_PX):
        self.folder, self.scene, self.shown_px = folder, scene, shown_px
        self.references: dict[str, dict | None] = {}  # "WxH" -> reference entry (reference())
        self._ref_arrays: dict[str, dict | None] = {}

    def _shown(self, values: np.ndarray, scale: im.Scale, size: str, name: str,
               shrink=im.shrink_mean) -> tuple[str, str | None]:
        """(data URI at the size shown, path of the native-size file or None): the file is
        written only where the page shows the image smaller than it is."""
        h, w = values.shape
        if im.shrink_factor(w, h, self.shown_px) == 1:
            return im.data_uri(values, scale), None
        relative = Path("images") / slug(self.scene) / size / f"{name}.png"
        im.write_png(values, scale, self.folder.root / relative)
        return im.data_uri(shrink(values, self.shown_px), scale), relative.as_posix()

    def reference(self, size: str, relative: str) -> dict | None:
        """The reference V of one image size (read once)."""
        if size not in self.references:
            z = self.folder.arrays(relative, "visibility", "covered",
                                   what=f"{self.scene} {size} reference")
            self._ref_arrays[size] = z
            self.references[size] = None
            if z is not None:
                uri, native = self._shown(im.visibility(z["visibility"], z["covered"]),
                                          im.VISIBILITY, size, "reference")
                self.references[size] = {"ref": uri, "native": {"ref": native}, "shaded": None}
        return self.references[size]

    def thumbnail(self, px: int = 64) -> str | None:
        """The largest reference, averaged down to ``px``, for the table of scenes."""
        stored = [(size, z) for size, z in self._ref_arrays.items() if z is not None]
        if not stored:
            return None
        _, z = max(stored, key=lambda kv: _pixels(kv[0]))
        return im.data_uri(im.shrink_mean(im.visibility(z["visibility"], z["covered"]), px),
                           im.VISIBILITY)

    def run(self, row) -> tuple[dict | None, str | None]:
        """(images of one run, None) or (None, why there are none)."""
        size = f"{int(row['width'])}x{int(row['height'])}"
        if row["status"] != "ok":
            return None, f"{row['status']}: {row.get('error') or 'no reason given'}"
        reference = self.reference(size, row.get("reference_array") or "")
        if reference is None:
            return None, "its reference is missing or damaged"
        z = self.folder.arrays(row.get("array") or "", "visibility", "covered",
                               what=f"{self.scene} {size} {row['technique']}")
        if z is None:
            return None, "its arrays are missing, damaged or outside the folder"
        ref, ref_covered = self._ref_arrays[size]["visibility"], self._ref_arrays[size]["covered"]
        v, covered = z["visibility"], z["covered"]
        if v.shape != ref.shape:
            return None, f"its V is {v.shape}, the reference {ref.shape}"
        compared = z["compared"] if "compared" in z else covered & ref_covered
        d = im.signed_error(v, ref, compared)
        visible = im.visibility(v, covered)
        name = slug(Path(row.get("array") or row["run_id"]).stem)
        out = {"native": {}, "crop": None, "shaded": None, "maps": []}
        out["v"], out["native"]["v"] = self._shown(visible, im.VISIBILITY, size, name)
        out["err"], out["native"]["err"] = self._shown(d, im.ERROR, size, f"{name}-error",
                                                       shrink=im.shrink_error)
        window = im.worst_edge_crop(d, ref, compared)
        if window is not None:
            out["crop"] = {"at": list(window),
                           "ref": im.data_uri(im.crop(im.visibility(ref, ref_covered), window),
                                              im.VISIBILITY),
                           "v": im.data_uri(im.crop(visible, window), im.VISIBILITY),
                           "err": im.data_uri(im.crop(d, window), im.ERROR)}
        if "shaded" in z and "shaded_reference" in z:
            shaded = np.where(covered, np.asarray(z["shaded"], np.float64), np.nan)
            out["shaded"], out["native"]["shaded"] = self._shown(shaded, im.SHADED, size,
                                                                 f"{name}-shaded")
            if reference["shaded"] is None:
                shaded_ref = np.where(ref_covered, np.asarray(z["shaded_reference"], np.float64),
                                      np.nan)
                reference["shaded"], reference["native"]["shaded"] = self._shown(
                    shaded_ref, im.SHADED, size, "reference-shaded")
        for key in sorted(k for k in z if k.startswith("map_")):
            values = np.asarray(z[key], np.float64)
            scale = im.map_scale(values)
            out["maps"].append({"name": key.removeprefix("map_"),
                                "uri": im.data_uri(im.shrink_mean(values, self.shown_px),
                                                   scale),
                                "lo": plots.number(scale.lo), "hi": plots.number(scale.hi)})
        return out, None


def _pixels(size: str) -> int:
    w, _, h = size.partition("x")
    return int(w) * int(h)
