"""Fill rate and the Roettger et al. Table 2 for ``sv``, measured (not a CI test).

    python -m techniques.sv_measure [--frames 7] [--warmup 2] [--table-scene crowd]

Prints two Markdown tables: the overdraw O of the silhouette-map paper's Table 1 (volume
fragments, depth test off / scene fragments) on crowd, castle and pins; and, per resolution,
the per-frame cost of each mask method and of the no-shadow G-buffer pass, as ratios.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness import registry
from harness.gl.context import get_context
from harness.scene import load_scene
from harness.technique import Frame, reset_gl_state

SCENE_FILE = Path(__file__).resolve().parent.parent / "scenes.yaml"
TABLE2 = {  # Roettger et al. Table 2, frames per second: screen, alpha, stencil, half, none
    256: (40.8, 42.4, 42.4, 39.1, 90.4),
    512: (29.9, 33.6, 29.1, 30.5, 89.2),
    1024: (9.3, 10.2, 8.9, 15.7, 44.6),
}
METHODS = {"screen": {"buffer": "screen"}, "alpha": {"buffer": "alpha"},
           "stencil": {"buffer": "stencil"}, "half": {"buffer": "alpha", "mask_res": "half"}}


def run(frame: Frame, params: dict, frames: int, warmup: int):
    """Median frame time (ms) of the technique's passes, per-pass medians, its extra columns."""
    cls = registry.get("sv")
    technique = cls(cls.Params(**params))
    frame.meter.release()
    from harness.gl.measure import PassMeter

    frame.meter = PassMeter()
    try:
        technique.prepare(frame)
        for i in range(warmup + frames):
            frame.meter.new_frame(measuring=i >= warmup)
            output = technique.render(frame)
    finally:
        technique.release()
        reset_gl_state()
    totals = sorted(frame.meter.frame_totals_ms)
    passes = {p.name: p.ms for p in frame.meter.passes()}
    return totals[len(totals) // 2], passes, output.extra


def overdraw_table(frames: int, warmup: int) -> None:
    print("| scene | buffer | volumes | volume triangles | volume fragments | scene fragments "
          "| O |")
    print("|---|---|---|---|---|---|---|")
    for name in ("crowd", "castle", "pins"):
        scene = load_scene(name, SCENE_FILE)
        frame = Frame(scene)
        try:
            for buffer in ("stencil", "alpha"):
                _, _, x = run(frame, {"buffer": buffer}, 1, 0)
                print(f"| {name} {scene.width}x{scene.height} | {buffer} | {x['volume_count']} "
                      f"| {x['volume_triangles']} | {x['volume_frags']} "
                      f"| {x['volume_scene_frags']} | {x['volume_overdraw']:.1f} |")
        finally:
            frame.release()


def table2(scene_name: str, frames: int, warmup: int) -> None:
    print(f"\nscene {scene_name}; ms per frame; ratio = (scene + technique) / scene "
          "(paper: fps_none / fps_method)")
    print("| size | no shadows (G-buffer) ms | " + " | ".join(
        f"{m} ms (ratio; paper)" for m in METHODS) + " |")
    print("|---|---|" + "---|" * len(METHODS))
    base = load_scene(scene_name, SCENE_FILE)
    for size, paper in TABLE2.items():
        frame = Frame(base.with_resolution(size, size))
        try:
            scene_ms, _ = frame.measure_scene_pass(frames, warmup)
            cells = []
            for (method, params), fps in zip(METHODS.items(), paper):
                ms, passes, _ = run(frame, params, frames, warmup)
                ratio = (scene_ms + ms) / scene_ms
                detail = ", ".join(f"{k} {v:.2f}" for k, v in passes.items())
                cells.append(f"{ms:.2f} ({ratio:.2f}; {paper[-1] / fps:.2f}) [{detail}]")
            print(f"| {size}^2 | {scene_ms:.2f} | " + " | ".join(cells) + " |")
        finally:
            frame.release()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=7)
    parser.add_argument("--warmup", type=int, default=2)
    parser.add_argument("--table-scene", default="crowd")
    args = parser.parse_args()
    context = get_context("osmesa")
    print(f"renderer: {context.renderer}\n")
    overdraw_table(args.frames, args.warmup)
    table2(args.table_scene, args.frames, args.warmup)


if __name__ == "__main__":
    main()
