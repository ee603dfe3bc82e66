"""Shadow volumes extruded on the GPU every frame, from geometry uploaded once (a helper of
the ``sv`` technique, not a technique).

What is uploaded depends on the geometry alone, in each part's model space:
- a closed part drawn as one silhouette volume: its edge mesh, each edge a degenerate quad
  carrying the planes of both faces it joins (McGuire et al. 2003, "Fast, practical and
  robust shadows"), which ``sv_edge.vert.glsl`` extrudes where the edge is a silhouette edge
  for the frame's light, and its faces, which ``sv_cap.vert.glsl`` makes the caps;
- any other part: its triangles, each made one volume by ``sv_polygon.geom.glsl``.
Stored per edge: two triangles (first the quad's half that is the whole side for a
directional light, whose far corners coincide, then the other half), six vertices without
an index buffer, so the vertex shader runs a known number of times: 3 per edge for a
directional light, 6 for a positional one (spot or point); 3 per face for the caps and the
per-triangle volumes.

The frame's light reaches the shaders as a uniform, so everything that depends on it runs on
the GPU inside the volume pass. So do moving objects: each part is drawn with its pose
(``Frame.part_poses``) as the ``model`` transform and the light brought into its model space,
parts that share a pose in one draw. :meth:`GpuVolumes.diagnostics` recounts in NumPy what
that pass built, for
the results' columns (silhouette edges, volumes, triangles); it is untimed, as a renderer
would not compute it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from OpenGL import GL

from harness.gl.geometry import VertexArray
from harness.gl.shaders import Program
from harness.scene import Light

from . import sv_cull, sv_volumes
from .sv_volumes import CleanMesh

# position, other end, plane of the face holding position -> other end, of its twin, far corner
EDGE_LAYOUT = (3, 3, 4, 4, 1)
# position, plane of its face
FACE_LAYOUT = (3, 4)
HERE = Path(__file__).parent


def face_planes(mesh: CleanMesh) -> np.ndarray:
    """(F, 4): each face's unit normal n and d = -n . corner, so n . x + d = 0 on it."""
    tri = mesh.vertices[mesh.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return np.concatenate([normal, -np.einsum("ij,ij->i", normal, tri[:, 0])[:, None]], axis=1)


def edge_faces(mesh: CleanMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each undirected edge of a closed mesh once: its ends a, b, the face that holds a -> b
    and the face that holds b -> a."""
    a, b, twin = sv_volumes.directed_edges(mesh)
    once = a < b
    face = np.repeat(np.arange(len(mesh.faces)), 3)
    return a[once], b[once], face[once], face[twin[once]]


def edge_quads(mesh: CleanMesh, out: np.ndarray | None = None) -> np.ndarray:
    """The edge mesh's vertices (6 E, 15), float32: first every edge's triangle (b, a, a at
    infinity), then every edge's (b, a at infinity, b at infinity), with ends swapped in the
    shader where the twin face is the lit one (the order of ``sv_volumes._sides``). Written
    corner by corner into ``out`` where given (a slice of the buffer being uploaded), never as
    a float64 array of the whole: on instancing@1e6 that was 1.1 GiB, and the parts' blocks
    concatenated took sv's prepare 2.3 GiB over what the process held (issue 53)."""
    a, b, face, twin_face = edge_faces(mesh)
    planes = face_planes(mesh)
    own, twin = planes[face], planes[twin_face]
    v = mesh.vertices
    out = np.empty((6 * len(a), 15), np.float32) if out is None else out
    near_b, near_a, far_a, far_b = (b, a, 0), (a, b, 0), (a, b, 1), (b, a, 1)
    for half, corners in zip(out.reshape(2, len(a), 3, 15),
                             ((near_b, near_a, far_a), (near_b, far_a, far_b))):
        for slot, (end, other, far) in zip(half.transpose(1, 0, 2), corners):
            slot[:, 0:3], slot[:, 3:6] = v[end], v[other]
            slot[:, 6:10], slot[:, 10:14], slot[:, 14] = own, twin, far
    return out


def face_corners(mesh: CleanMesh, out: np.ndarray | None = None) -> np.ndarray:
    """The faces' corners with their face's plane (3 F, 7), float32, written into ``out``
    where given (as :func:`edge_quads`)."""
    out = np.empty((3 * len(mesh.faces), 7), np.float32) if out is None else out
    corners = out.reshape(-1, 3, 7)
    corners[..., 0:3] = mesh.vertices[mesh.faces]
    corners[..., 3:7] = face_planes(mesh)[:, None]
    return out


def light_vector(light: Light) -> np.ndarray:
    """The light as the homogeneous point sv_extrude.glsl expects (world space; a part with a
    model transform M would get inverse(M) times it, with ``model`` = M)."""
    return (np.append(-light.direction, 0.0) if light.type == "directional"
            else np.append(light.position, 1.0))


@dataclass(frozen=True)
class PartRange:
    """Where a part's vertices lie in a buffer: first vertex and count."""

    first: int
    count: int


def _ranges(counts: list[int]) -> list[PartRange]:
    starts = np.concatenate([[0], np.cumsum(counts, dtype=np.int64)])
    return [PartRange(int(s), int(c)) for s, c in zip(starts, counts)]


def _program(vertex: str, geometry: str | None = None, **defines) -> Program:
    return Program(HERE / vertex, HERE / "sv_volume.frag.glsl", defines or None,
                   geometry=HERE / geometry if geometry else None)


class GpuVolumes:
    """The volumes of every part, drawn in the volume pass (the caller sets depth, stencil and
    blend state). ``single[i]``: part i is one silhouette volume; ``caps``: z-fail's caps;
    ``increments_first``: the state machine's order, volume by volume, the faces that
    increment the count first (per-triangle volumes: by the geometry shader; a silhouette
    volume, convex wherever that order matters: drawn twice, culled one way then the other)."""

    def __init__(self, names: list[str], meshes: list[CleanMesh], single: list[bool], *,
                 caps: bool, increments_first: bool, nested_counts: bool, cull: bool = False,
                 clamp: bool = False):
        self.caps, self.increments_first = caps, increments_first
        self.names, self.meshes, self.single = names, meshes, single
        self.nested_counts = nested_counts
        closed = [m for m, s in zip(meshes, single) if s and len(m.faces)]
        open_ = [m for m, s in zip(meshes, single) if not s and len(m.faces)]
        # the scene part each drawn closed and open part is, whose pose places it
        self.closed_parts, self.open_parts = (
            [i for i, (m, s) in enumerate(zip(meshes, single)) if s == one and len(m.faces)]
            for one in (True, False))
        self.edge_meshes = [edge_faces(m) for m in closed]
        self.edge_ranges = _ranges([6 * len(e[0]) for e in self.edge_meshes])
        self.face_ranges = _ranges([3 * len(m.faces) for m in closed])
        self.polygon_ranges = _ranges([3 * len(m.faces) for m in open_])
        self.edges = VertexArray(_interleaved(closed, self.edge_ranges, 15, edge_quads),
                                 EDGE_LAYOUT)
        self.faces = VertexArray(_interleaved(closed, self.face_ranges, 7, face_corners),
                                 FACE_LAYOUT)
        self.polygons = VertexArray(_interleaved(open_, self.polygon_ranges, 7, face_corners),
                                    FACE_LAYOUT)
        self.edge_program = _program("sv_edge.vert.glsl")
        self.cap_program = _program("sv_cap.vert.glsl")
        # cull reads the receivers' grid in the per-triangle volumes' geometry shader; the
        # clamp, their light depths in the fragment shader (compiled apart: llvmpipe would
        # fetch them, even where a uniform turned the test off)
        culling = {"CULL": 1, "GRID_SIZE": sv_cull.GRID} if cull else {}
        if clamp:
            culling["CLAMP"] = 1
        self.polygon_program = _program("sv_polygon.vert.glsl", "sv_polygon.geom.glsl",
                                        EDGE_ON=repr(sv_volumes.DEGENERATE), **culling)
        self.programs = (self.edge_program, self.cap_program, self.polygon_program)

    def draw(self, light: Light, view_proj: np.ndarray, poses: np.ndarray,
             receivers: dict | None = None, **fragment_uniforms) -> None:
        """All volumes for ``light``, each part placed by its pose in ``poses`` (P, 4, 4);
        ``fragment_uniforms`` go to sv_volume.frag.glsl; ``receivers``: the cull's grid
        (``sv_cull.ReceiverGrid.uniforms``), None for no culling."""
        for program in self.programs:
            program.use().set(view_proj=view_proj, caps=self.caps,
                              increments_first=self.increments_first, **fragment_uniforms)
        self.polygon_program.use().set(**(receivers or {"cull_on": False}))
        positional = light.positional
        for pose, closed, open_ in self._batches(poses):
            self._place(light, pose)
            if self.increments_first and closed:
                self._silhouette_increments_first(closed[0], positional,
                                                  fragment_uniforms["front_increments"])
                continue
            self._edges(closed, positional)
            self._faces(self.cap_program, self.faces, [self.face_ranges[i] for i in closed],
                        self.caps)
            self._faces(self.polygon_program, self.polygons,
                        [self.polygon_ranges[i] for i in open_], True)

    def _batches(self, poses: np.ndarray) -> list[tuple[np.ndarray, list[int], list[int]]]:
        """What one model transform draws, in draw order: (pose, closed parts, open parts),
        by index into the edge and polygon ranges."""
        drawn = sorted([(part, True, i) for i, part in enumerate(self.closed_parts)]
                       + [(part, False, i) for i, part in enumerate(self.open_parts)])
        batches: list[tuple[np.ndarray, list[int], list[int]]] = []
        for part, closed, index in drawn:
            batch = self._batch_joined(batches, poses[part], closed)
            if batch is None:
                batch = (poses[part], [], [])
                batches.append(batch)
            batch[1 if closed else 2].append(index)
        return batches

    def _batch_joined(self, batches: list, pose: np.ndarray, closed: bool):
        """The batch a part joins, None for a new one. The stencil counts in any order: one
        batch per distinct pose (one on a still scene). The state machine's order is part by
        part: a silhouette volume alone, consecutive per-triangle parts of one pose together."""
        if not self.increments_first:
            return next((b for b in batches if np.array_equal(b[0], pose)), None)
        last = batches[-1] if batches else None
        joins = not closed and last is not None and not last[1] and np.array_equal(last[0], pose)
        return last if joins else None

    def _place(self, light: Light, pose: np.ndarray) -> None:
        """``model`` = the rigid ``pose``, and the light moved into the part's model space,
        where the vertices and face planes are (inverse(pose) times the light's vector)."""
        light_in_part = np.linalg.solve(pose, light_vector(light))
        for program in self.programs:
            program.use().set(light=light_in_part, model=pose)

    def _silhouette_increments_first(self, part: int, positional: bool,
                                     front_increments: bool) -> None:
        """A silhouette volume drawn twice, culled so that its increments come first."""
        GL.glEnable(GL.GL_CULL_FACE)
        for culled_front in (not front_increments, front_increments):
            GL.glCullFace(GL.GL_FRONT if culled_front else GL.GL_BACK)
            self._edges([part], positional)
            self._faces(self.cap_program, self.faces, self.face_ranges[part:part + 1],
                        self.caps)
        GL.glDisable(GL.GL_CULL_FACE)

    def _edges(self, parts, positional: bool) -> None:
        """Each part's edge quads: for a directional light only their first halves."""
        ranges = [self.edge_ranges[i] for i in parts]
        self.edge_program.use()
        _multi_draw(self.edges, [r.first for r in ranges],
                    [r.count if positional else r.count // 2 for r in ranges])

    @staticmethod
    def _faces(program: Program, vertices: VertexArray, ranges: list[PartRange],
               wanted: bool) -> None:
        if wanted:
            program.use()
            _multi_draw(vertices, [r.first for r in ranges], [r.count for r in ranges])

    def vertex_count(self, positional: bool) -> int:
        """Vertex shader runs of one :meth:`draw`: what the edge mesh implies."""
        edges = sum(r.count for r in self.edge_ranges) // (1 if positional else 2)
        caps = sum(r.count for r in self.face_ranges) if self.caps else 0
        return (edges + caps) * (2 if self.increments_first else 1) + self.polygons.count

    def diagnostics(self, light: Light, poses: np.ndarray) -> tuple[dict, list[str]]:
        """What :meth:`draw` builds for ``light`` and ``poses``, recounted in double precision
        from the moved meshes (untimed):
        silhouette edges, volumes and the triangles that are not degenerate (each side a
        triangle for a directional light, a quad of two for a spot or point light); and the
        warnings of ``sv_volumes.build``."""
        positional = light.positional
        sides = 2 if positional else 1
        counts = dict.fromkeys(("silhouette_edges", "volume_count", "volume_triangles"), 0)
        warnings = []
        closed = iter(self.edge_meshes)
        for name, mesh, one in zip(self.names, sv_volumes.placed(self.meshes, poses),
                                   self.single):
            if not len(mesh.faces):
                warnings.append(f"{name}: no non-degenerate triangles; casts no shadow")
                continue
            if one:
                _, _, face, twin_face = next(closed)
                lit = sv_volumes.light_facing(mesh.vertices[mesh.faces], light) > 0
                edges = int((lit[face] != lit[twin_face]).sum())
                caps = int(lit.sum()) + (int((~lit).sum()) if positional else 0)
                counts["silhouette_edges"] += edges
                counts["volume_count"] += (volumes := 1)
                counts["volume_triangles"] += sides * edges + (caps if self.caps else 0)
            else:
                volumes = len(sv_volumes.toward_light(mesh, light))
                counts["volume_count"] += volumes
                caps = 1 + positional if self.caps else 0
                counts["volume_triangles"] += volumes * (3 * sides + caps)
            notes = sv_volumes.part_notes(mesh, light, single=one,
                                          nested_counts=self.nested_counts, volumes=volumes)
            if notes:
                warnings.append(f"{name}: " + "; ".join(notes))
        return {**counts, "volume_vertices": self.vertex_count(positional)}, warnings

    def release(self) -> None:
        for resource in (self.edges, self.faces, self.polygons, *self.programs):
            resource.release()


def _interleaved(meshes: list[CleanMesh], ranges: list[PartRange], width: int,
                 write) -> np.ndarray:
    """One float32 buffer of the meshes' vertices, each mesh's written in place at its range
    by ``write(mesh, out)``: no mesh's block is made apart and copied in."""
    out = np.empty((sum(r.count for r in ranges), width), np.float32)
    for mesh, r in zip(meshes, ranges):
        write(mesh, out[r.first:r.first + r.count])
    return out


def _multi_draw(vertices: VertexArray, firsts: list[int], counts: list[int]) -> None:
    drawn = [(f, c) for f, c in zip(firsts, counts) if c]
    if not drawn:
        return
    first, count = (np.array(x, np.int32) for x in zip(*drawn))
    GL.glBindVertexArray(vertices.vao)
    GL.glMultiDrawArrays(GL.GL_TRIANGLES, first, count, len(drawn))
    GL.glBindVertexArray(0)
