"""The scene drawn as an indexed mesh (harness/gl/geometry.py SceneMesh: shared vertices,
glDrawElements, flat normal and albedo read per face at gl_PrimitiveID) against the way it was
drawn before, kept here as the oracle: 3 unshared vertices per triangle carrying the face's
normal and albedo (tests/data/oracle_glsl/gbuffer_unshared.*.glsl, the old G-buffer shaders)."""

from __future__ import annotations


import numpy as np
import pytest

from harness.technique import registry
from harness.technique import Frame, reset_gl_state
from helpers import DATA

ORACLE_GLSL = DATA / "oracle_glsl"
# every shipped kind of geometry: primitives, a tessellated crowd, a mesh file (jeep), a spot
SCENES = ("box_plane", "sphere_plane", "castle", "crowd", "pins", "jeep")


def unrolled(scene):
    """The old scene vertex array: position, flat normal and albedo per unrolled vertex."""
    from harness.gl.geometry import VertexArray

    t = len(scene.triangles)
    data = np.concatenate([scene.triangles.reshape(t, 3, 3),
                           np.repeat(scene.face_normals[:, None, :], 3, axis=1),
                           np.repeat(scene.face_albedo[:, None, None], 3, axis=1)], axis=2)
    return VertexArray(data, (3, 3, 1))


class UnsharedScene:
    """A stand-in for ``Frame.geometry`` drawing the unrolled vertices (the map passes read
    only location 0, the position, from either)."""

    def __init__(self, scene):
        self.array = unrolled(scene)

    def bind_face_attributes(self, unit):
        return unit

    def draw(self):
        self.array.draw()

    def release(self):
        self.array.release()


def as_before(frame: Frame, old: UnsharedScene):
    """Put ``frame`` on the unshared path: its G-buffer rendered by the old shaders from the
    unrolled vertices, its scene draws from them too."""
    from harness.gl.shaders import Program

    program = Program(ORACLE_GLSL / "gbuffer_unshared.vert.glsl",
                      ORACLE_GLSL / "gbuffer_unshared.frag.glsl")
    indexed, frame.geometry = frame.geometry, old
    indexed.release()
    gbuffer_program, frame.gbuffer.program = frame.gbuffer.program, program
    gbuffer_program.release()
    frame.arrays = frame._camera_pass()


def sm_v(frame: Frame) -> np.ndarray:
    cls = registry.get("sm")
    run = cls(cls.Params())
    try:
        run.prepare(frame)
        frame.meter.new_frame(False)
        run.update(frame)
        return run.render(frame).visibility.copy()
    finally:
        run.release()
        reset_gl_state()


@pytest.mark.parametrize("name", SCENES)
def test_indexed_scene_gives_the_unshared_gbuffer_and_v(scene_at, shipped_scenes, gl_context,
                                                         name):
    """On shipped scenes at their size: every G-buffer array (position, normal, albedo,
    coverage) and sm's V are equal bit for bit from the indexed mesh and from the unshared
    vertices: the same float32 positions in the same face and vertex order rasterise alike,
    and the face's normal and albedo read at gl_PrimitiveID are the values the vertices
    carried. Catches faces out of triangle order (a normal read for the wrong face), an index
    offset missing between parts (garbage triangles), and a per-vertex (smooth) normal."""
    scene = scene_at(name, *shipped_scenes[name].resolution)
    indexed = Frame(scene)
    before = Frame(scene)
    try:
        as_before(before, UnsharedScene(scene))
        for field in ("position", "normal", "albedo", "covered"):
            np.testing.assert_array_equal(getattr(indexed.arrays, field),
                                          getattr(before.arrays, field), err_msg=field)
        np.testing.assert_array_equal(sm_v(indexed), sm_v(before))
    finally:
        indexed.release()
        before.release()


@pytest.mark.parametrize("name", ("castle", "crowd"))
def test_the_map_pass_shades_each_shared_vertex_about_once(scene_at, evaluate, name):
    """sm's map pass counts (pipeline statistics) about one vertex invocation per shared
    vertex, not three per triangle: at least the mesh's vertex count and within 1.25 times it
    (llvmpipe's vertex cache re-shades a vertex shared across its chunks: seen 1.02 on castle,
    1.12 on crowd), against 3 T = 4.9 and 5.9 times it drawn unshared. Catches the scene drawn
    unrolled again (glDrawArrays of 3 T vertices)."""
    scene = scene_at(name, 128)
    vertices, faces = scene.indexed
    row = evaluate(scene, "sm", {"res": 256}).row
    if row["vertex_invocations"] is None:
        pytest.skip("the driver counts no pipeline statistics")
    (shadow_map,) = [p for p in row["passes"] if p["name"] == "shadow_map"]
    assert len(vertices) <= shadow_map["vertex_invocations"] <= 1.25 * len(vertices)
    assert shadow_map["primitives"] == len(faces)
    assert 3 * len(faces) > 4 * len(vertices)  # the bound above tells the two apart
