"""Fill rate and the Roettger et al. Table 2 for ``sv``, measured (not a CI test).

    .venv/bin/python benchmarks/sv_table2.py [--frames 7] [--warmup 2] [--table-scene crowd]

Prints two Markdown tables: the overdraw O of the silhouette-map paper's Table 1 (volume
fragments, depth test off / scene fragments) on crowd, castle and pins; and, per resolution,
the per-frame cost of each mask method (z-pass, as in the paper) and of the no-shadow G-buffer
pass, as ratios, with each method's scene passes (Table 1; the G-buffer pass is the first) and
the quarter-size mask of section 5 (10.2 -> 23.6 Hz at 1024^2).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.gl.context import get_context
from harness.run import evaluate
from harness.scene import load_scene

SCENE_FILE = Path(__file__).resolve().parent.parent / "scenes.yaml"
TABLE2 = {  # Roettger et al. Table 2, frames per second: screen, alpha, stencil, half, none
    256: (40.8, 42.4, 42.4, 39.1, 90.4),
    512: (29.9, 33.6, 29.1, 30.5, 89.2),
    1024: (9.3, 10.2, 8.9, 15.7, 44.6),
}
QUARTER_FPS = {1024: 23.6}  # section 5: "a quarter of the screen size", alpha buffer
METHODS = {"screen": {"buffer": "screen"}, "alpha": {"buffer": "alpha"},
           "stencil": {"buffer": "stencil"}, "half": {"buffer": "alpha", "mask_res": "half"},
           "quarter": {"buffer": "alpha", "mask_res": "quarter"}}


def overdraw_table() -> None:
    print("| scene | buffer | volumes | volume triangles | volume fragments | scene fragments "
          "| O |")
    print("|---|---|---|---|---|---|---|")
    for name in ("crowd", "castle", "pins"):
        scene = load_scene(name, SCENE_FILE)
        for buffer in ("stencil", "alpha"):
            x = evaluate(scene, "sv", {"buffer": buffer}).row
            print(f"| {name} {scene.width}x{scene.height} | {buffer} | {x['volume_count']} "
                  f"| {x['volume_triangles']} | {x['frags_shadow']} | {x['frags_scene']} "
                  f"| {x['overdraw']:.1f} |")


def table2(scene_name: str, frames: int, warmup: int) -> None:
    print(f"\nscene {scene_name}; ms per frame; ratio = (scene + technique) / scene "
          "(paper: fps_none / fps_method)")
    print("| size | no shadows (G-buffer) ms | " + " | ".join(
        f"{m} ms (ratio; paper)" for m in METHODS) + " |")
    print("|---|---|" + "---|" * len(METHODS))
    base = load_scene(scene_name, SCENE_FILE)
    passes = {}
    for size, paper in TABLE2.items():
        scene = base.with_resolution(size, size)
        fps = dict(zip(METHODS, paper[:-1]), quarter=QUARTER_FPS.get(size))
        cells, scene_ms = [], None
        for method, params in METHODS.items():
            row = evaluate(scene, "sv", {**params, "method": "zpass"}, frames=frames,
                           warmup=warmup).row
            scene_ms, passes[method] = row["scene_ms"], row["scene_passes"]
            ratio = (scene_ms + row["time_ms"]) / scene_ms
            theirs = f"{paper[-1] / fps[method]:.2f}" if fps[method] else "-"
            detail = ", ".join(f"{p['name']} {p['ms']:.2f}" for p in row["passes"])
            cells.append(f"{row['time_ms']:.2f} ({ratio:.2f}; {theirs}) [{detail}]")
        print(f"| {size}^2 | {scene_ms:.2f} | " + " | ".join(cells) + " |")
    print("\nscene passes per frame, the G-buffer's included: "
          + ", ".join(f"{m} {n}" for m, n in passes.items()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=7)
    parser.add_argument("--warmup", type=int, default=2)
    parser.add_argument("--table-scene", default="crowd")
    args = parser.parse_args()
    context = get_context()
    print(f"renderer: {context.renderer}\n")
    overdraw_table()
    table2(args.table_scene, args.frames, args.warmup)


if __name__ == "__main__":
    main()
