"""Shadow-volume geometry built on the CPU every frame it is drawn (a helper of the ``sv``
technique, not a technique).

:class:`NearClipPolygons`: the near-plane clip polygons (Roettger et al. section 3.2), which
stay on the CPU in double precision (float32 world coordinates far from the origin lose a
polygon a near distance from the eye); they depend on the light, the camera and where moving
parts are, so they are computed inside the volume pass, every frame, from the meshes moved by
the frame's part poses.

:class:`CpuVolumes`: all volumes built in NumPy (``sv_volumes.build``) and uploaded inside
the volume pass, every frame. Two uses only: the test oracle that GPU-extruded volumes are
compared with (:func:`oracle`), and nearclip in the alpha and screen buffers, whose state
machine needs each volume's clip polygons drawn with its increments, before its decrements,
an order the GPU volumes (drawn part by part, per-triangle volumes by a geometry shader) do
not give.
"""

from __future__ import annotations

import numpy as np

from harness.gl.geometry import VertexArray
from harness.scene import Light, MeshPart
from harness.technique import Technique

from . import sv_volumes
from .sv_volumes import CleanMesh

# homogeneous world position and 0, or a clip polygon's normalised device x, y, 0, 1 and 1
VOLUME_LAYOUT = (4, 1)


def _program():
    return Technique.shader(__file__, "sv_volume.vert.glsl", "sv_volume.frag.glsl")


def _near_rows(polygons: np.ndarray) -> np.ndarray:
    rows = np.zeros(polygons.shape[:2] + (5,))
    rows[..., :2], rows[..., 3:] = polygons, 1.0
    return rows


class NearClipPolygons:
    """Each volume's cross-section with the near plane, drawn as front faces."""

    def __init__(self, meshes: list[CleanMesh], single: list[bool]):
        self.meshes, self.single = meshes, single
        self.vertices = VertexArray(np.zeros((0, 5), np.float32), VOLUME_LAYOUT)
        self.program = _program()
        self.triangles = 0

    def draw(self, light: Light, view_proj: np.ndarray, poses: np.ndarray,
             **fragment_uniforms) -> None:
        casters, owners = sv_volumes.light_casters(sv_volumes.placed(self.meshes, poses),
                                                   self.single, light)
        polygons, _ = sv_volumes.near_clip_polygons(casters, owners, light, view_proj)
        self.triangles = len(polygons)
        self.vertices.update(_near_rows(polygons).reshape(-1, 5))
        self.program.use().set(view_proj=view_proj, **fragment_uniforms)
        self.vertices.draw()

    def release(self) -> None:
        self.vertices.release()
        self.program.release()


class CpuVolumes:
    """The volumes of ``sv_volumes.build`` with ``params`` (the technique's), drawn in the
    state machine's order for the alpha and screen buffers."""

    def __init__(self, parts: list[MeshPart], meshes: list[CleanMesh], params):
        self.parts, self.meshes, self.params = parts, meshes, params
        self.vertices = VertexArray(np.zeros((0, 5), np.float32), VOLUME_LAYOUT)
        self.program = _program()
        self.volume_set = None
        self.near_clip_triangles = 0

    def draw(self, light: Light, view_proj: np.ndarray, poses: np.ndarray,
             **fragment_uniforms) -> None:
        p = self.params
        self.volume_set = sv_volumes.build(
            self.parts, light, caps=p.method == "zfail",
            nested_counts=p.buffer == "stencil" or p.normalize == "max", grouping=p.volumes,
            meshes=sv_volumes.placed(self.meshes, poses))
        vertices, self.near_clip_triangles = self._vertices(light, view_proj)
        self.vertices.update(vertices)
        self.program.use().set(view_proj=view_proj, **fragment_uniforms)
        self.vertices.draw()

    def _vertices(self, light: Light, view_proj: np.ndarray) -> tuple[np.ndarray, int]:
        """Volume vertices (N, 5), triangles in the state machine's order for alpha and
        screen, and the number of clip-polygon triangles."""
        volumes, p = self.volume_set, self.params
        triangles = volumes.triangles.astype(np.float64)
        owner = volumes.volume_of
        increments = sv_volumes.camera_facing(triangles, view_proj) == (p.method != "zfail")
        rows = np.concatenate([triangles, np.zeros(triangles.shape[:2] + (1,))], axis=2)
        near = np.zeros((0, 3, 2))
        if p.method == "nearclip":
            near, near_owner = sv_volumes.near_clip_polygons(volumes.casters,
                                                             volumes.caster_volume, light,
                                                             view_proj)
            rows = np.concatenate([rows, _near_rows(near)])
            owner = np.concatenate([owner, near_owner])
            increments = np.concatenate([increments, np.ones(len(near), bool)])  # front faces
        if p.buffer != "stencil":
            rows = rows[sv_volumes.draw_order(owner, increments)]
        return rows.reshape(-1, 5), len(near)

    def diagnostics(self, light: Light, poses: np.ndarray) -> tuple[dict, list[str]]:
        """The last drawn volumes' counts and warnings (drawn for ``light`` and ``poses``)."""
        volumes = self.volume_set
        triangles = len(volumes.triangles)
        return ({"silhouette_edges": volumes.silhouette_edges,
                 "volume_count": volumes.volume_count, "volume_triangles": triangles,
                 "volume_vertices": 3 * triangles,
                 "near_clip_triangles": self.near_clip_triangles}, list(volumes.warnings))

    def release(self) -> None:
        self.vertices.release()
        self.program.release()


def oracle(technique, frame) -> tuple[CpuVolumes, None]:
    """In place of ``ShadowVolumes._volume_geometry``: every combination drawn from the
    CPU-built volumes, the reference the GPU-extruded ones are tested against."""
    return CpuVolumes(frame.scene.parts, technique.meshes, technique.params), None
