"""Issue 49's texels-per-pixel bar: the share of each scene's receivers whose map texel is
between 0.5 and 2 pixels across (techniques.common.footprint.texel_over_pixel, per pixel, in
the map or level that pixel reads), for vsm, csm and sm at their defaults, as Markdown. The
results' columns keep the median and the 95th percentile only.

    PYTHONPATH=. .venv/bin/python benchmarks/texel_band.py [--scenes a,b] [--triangles 1e5,1e6]
"""

from __future__ import annotations

import argparse

import numpy as np

from harness.gl.context import get_context
from harness.scene import load_scene
from harness.technique import Frame, NotApplicable, registry, reset_gl_state
from techniques.common.footprint import texel_ratios

SHIPPED = ("sphere_plane", "box_plane", "pins", "castle", "crowd", "terrain_long", "slant_edge",
           "silhouette_hard", "camera_in_shadow", "jeep", "alpha_checker", "alpha_fence",
           "alpha_cards_grazing", "alpha_card_edge_on")
FAMILIES = ("tessellation", "instancing", "architecture", "foliage", "cards")
BAND = (0.5, 2.0)


def ratios(frame: Frame, name: str) -> np.ndarray:
    """Per receiver, texel over pixel in the map it reads, for technique ``name`` at its
    defaults after one frame (vsm's levels and csm's cascades are the frame's)."""
    cls = registry.get(name)
    technique = cls(cls.Params())
    technique.prepare(frame)
    try:
        technique.update(frame)
        technique.render(frame)
        if name == "vsm":
            return texel_ratios(frame, technique.levels.map_grids, technique.level_map(frame))
        if name == "csm":
            return texel_ratios(frame, technique.map_grids(),
                                np.nan_to_num(technique.cascade_map(frame), nan=-1))
        light_map = technique.passes.map
        return texel_ratios(frame, [(light_map.frustum.view_proj, light_map.res)])
    finally:
        technique.release()
        reset_gl_state()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=",".join(SHIPPED))
    parser.add_argument("--triangles", default="1e5,1e6", help="the families' sizes")
    parser.add_argument("--techniques", default="vsm,csm,sm")
    args = parser.parse_args()
    names = [s for s in args.scenes.split(",") if s]
    names += [f"{family}@{n}" for family in FAMILIES for n in args.triangles.split(",") if n]
    techniques = args.techniques.split(",")
    get_context()
    print("| scene | " + " | ".join(f"{t}: in [0.5, 2] %, median, p5-p95" for t in techniques)
          + " |")
    print("|---" * (len(techniques) + 1) + "|")
    for name in names:
        frame = Frame(load_scene(name))
        cells = []
        try:
            for technique in techniques:
                try:
                    r = ratios(frame, technique)
                except NotApplicable as error:
                    cells.append(f"declined ({error})")
                    continue
                inside = 100 * np.mean((r >= BAND[0]) & (r <= BAND[1]))
                p5, median, p95 = np.percentile(r, [5, 50, 95])
                cells.append(f"{inside:.1f}, {median:.2f}, {p5:.2f}-{p95:.2f}")
        finally:
            frame.release()
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
