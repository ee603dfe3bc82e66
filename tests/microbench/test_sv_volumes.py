"""sv's volume pass on a large instanced scene (issue 22), in units of the G-buffer pass.

80 closed spheres of 1,280 triangles (102,400) over a ground plane, 512x512, directional
light. The volume pass is drawn once with GL_RASTERIZER_DISCARD (the vertex cost: the edge
mesh and caps through the vertex shader, nothing rasterised) and once normally (vertex and
fill cost); and sv's whole frame. Each benchmark's ``extra_info`` holds its median over the
G-buffer pass's (``per_scene_pass``). Run:

    pytest tests/microbench/test_sv_volumes.py -p no:randomly

``SV_BENCH_SCENE=instancing@1e6`` (a family scene of scenes.yaml at a size, at 512x512) runs
the same on it instead, e.g. the forest at 10^6 or ``architecture@1e5``'s open parts.
"""

from __future__ import annotations

import os

import pytest
from helpers import ROOT

ROUNDS = 5
SPHERES = (10, 8)
SCENE = {
    "resolution": [512, 512],
    "camera": {"position": [0, -26, 18], "target": [0, 0, 0], "up": [0, 0, 1], "yfov": 55,
               "near": 0.1, "far": 200},
    "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
    "objects": [
        {"shape": "plane", "size": [40, 40]},
        {"shape": "sphere", "radius": 0.9, "subdivisions": 3, "translate": [-11.25, -8.75, 1.5],
         "array": {"count": [*SPHERES, 1], "step": [2.5, 2.5, 0]}},
    ],
}
medians: dict[str, float] = {}


def _scene():

    from harness import config
    from harness.scene import build_scene

    chosen = os.environ.get("SV_BENCH_SCENE")
    if not chosen:
        return build_scene("sv_spheres", config.Scene(**SCENE))
    family, _, size = chosen.partition("@")
    scene_file = ROOT / "scenes.yaml"
    sized = config.load_scenes(scene_file)[family].at_triangles(int(float(size)))
    sized = sized.model_copy(update={"resolution": (512, 512)})
    return build_scene(chosen, sized, scene_file)


@pytest.fixture(scope="module")
def spheres(gl_context):
    from harness.technique import Frame, reset_gl_state
    from techniques.sv.sv import ShadowVolumes

    frame = Frame(_scene())
    technique = ShadowVolumes(ShadowVolumes.Params())
    technique.prepare(frame)
    technique.render(frame)  # sets its camera and counts its fill
    yield frame, technique
    technique.release()
    reset_gl_state()
    frame.release()


def _run(benchmark, name: str, work) -> None:
    from OpenGL import GL

    def timed():
        work()
        GL.glFinish()

    benchmark.pedantic(timed, rounds=ROUNDS, warmup_rounds=1)
    if benchmark.disabled:  # make test runs each benchmark once, untimed
        return
    medians[name] = benchmark.stats.stats.median
    benchmark.extra_info["per_scene_pass"] = round(medians[name] / medians["scene"], 3)


def test_gbuffer_pass(benchmark, spheres):
    frame, _ = spheres
    medians["scene"] = 1.0  # until measured: the unit itself
    _run(benchmark, "scene", lambda: frame.gbuffer.render(frame.geometry,
                                                          frame.camera.view_proj))
    triangles = sum(len(p.faces) for p in frame.scene.parts)
    assert triangles > 90_000
    benchmark.extra_info["triangles"] = triangles


def test_volume_pass_vertex_cost(benchmark, spheres):
    from OpenGL import GL

    frame, technique = spheres

    def discarded():
        GL.glEnable(GL.GL_RASTERIZER_DISCARD)
        technique._volume_pass(frame)
        GL.glDisable(GL.GL_RASTERIZER_DISCARD)

    technique.mask.bind()
    _run(benchmark, "vertex", discarded)
    benchmark.extra_info["silhouette_edges"] = technique.fill["silhouette_edges"]


def test_volume_pass_fill_cost(benchmark, spheres):
    frame, technique = spheres
    technique.mask.bind()
    _run(benchmark, "volumes", lambda: technique._volume_pass(frame))
    benchmark.extra_info["volume_fragments"] = technique.fill["volume_frags"]


def test_whole_frame(benchmark, spheres):
    frame, technique = spheres
    _run(benchmark, "frame", lambda: technique.render(frame))
