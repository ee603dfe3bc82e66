"""Silhouette edges seen from the light, and the thin quads that rasterise them into a
silhouette map (Sen, Cammarano, Hanrahan 2003, sections 2 and 3.1). A helper, not a technique.

Per frame the edges are found and widened on the GPU from the :class:`EdgeMesh` built once in
``prepare`` (``silhouette_edges.vert.glsl``, ``silhouette_edges.geom.glsl``). The NumPy path
(:meth:`EdgeAdjacency.silhouette`, :func:`project_edges`, :func:`edge_quads`, drawn by
``silhouette_quads.vert.glsl``) does the same work on the CPU and stays only as the tests'
oracle."""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from harness.gl.geometry import BufferTexture, VertexArray
from harness.scene import BuiltScene, Light
from harness.scene.transforms import LightFrustum

# Half-width and end extension of an edge's quad, in texels. A texel the segment crosses has
# its centre within sqrt(2)/2 of the segment, so a quad this wide covers that centre.
QUAD_HALF_WIDTH = 0.75

# Floats per quad vertex: position (2), segment endpoints A and B (2 + 2), their depths (2).
VERTEX_FLOATS = 8
VERTEX_SIZES = (2, 2, 2, 2)

# Floats per edge of the edge mesh: endpoints A and B (3 + 3), then where its faces' list starts
# and how many faces it has, then its part (float attributes: exact integers below 2^24).
EDGE_SIZES = (3, 3, 2, 1)
MAX_FACE_REFERENCES = 2 ** 24
# Texture units of the edge mesh's buffer textures: face list, face normals and part poses
# (unit 0 is the depth map's, SilhouetteMap.draw_edges).
EDGE_FACES_UNIT, FACE_NORMALS_UNIT, PART_POSES_UNIT = 1, 2, 3


class EdgeAdjacency:
    """Every edge of the scene's meshes with the faces around it, built once per scene.

    Vertices are merged per part (``MeshPart``), so an interior edge has two faces and a
    boundary edge of an open mesh has one.
    """

    def __init__(self, scene: BuiltScene):
        offsets = np.cumsum([0] + [len(p.vertices) for p in scene.parts[:-1]])
        self.vertices = np.concatenate([p.vertices for p in scene.parts]).astype(np.float64)
        faces = np.concatenate([p.faces + o for p, o in zip(scene.parts, offsets)])
        self.part_of_vertex = np.repeat(np.arange(len(scene.parts)),
                                        [len(p.vertices) for p in scene.parts])
        corner = self.vertices[faces]
        self.face_normals = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
        self.face_centroids = corner.mean(axis=1)
        half_edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1).astype(np.int64)
        # one int64 key per edge, (first, second) in lexicographic order: np.unique over rows
        # (axis=0) sorts them as records, 10x slower (2.4 of 16 s in test_fair_bias's runs)
        vertices = max(len(self.vertices), 1)
        keys, self.edge_of_half, self.faces_per_edge = np.unique(
            half_edges[:, 0] * vertices + half_edges[:, 1], return_inverse=True,
            return_counts=True)
        self.edges = np.column_stack([keys // vertices, keys % vertices])
        self.edge_of_half = self.edge_of_half.ravel()
        self.face_of_half = np.repeat(np.arange(len(faces)), 3)

    def silhouette(self, light: Light) -> np.ndarray:
        """Endpoints (E, 2, 3) of the edges between a light-facing and a back-facing face,
        plus the boundary edges of open meshes."""
        if light.type == "directional":
            to_light = -light.direction[None, :]
        else:
            to_light = light.position[None, :] - self.face_centroids
        facing = np.einsum("ij,ij->i", self.face_normals, np.broadcast_to(
            to_light, self.face_normals.shape)) > 0
        facing_per_edge = np.bincount(self.edge_of_half, weights=facing[self.face_of_half],
                                      minlength=len(self.edges))
        mixed = (facing_per_edge > 0) & (facing_per_edge < self.faces_per_edge)
        keep = mixed | (self.faces_per_edge == 1)
        return self.vertices[self.edges[keep]]


class EdgeMesh:
    """Every edge of the scene on the GPU, geometry only, for ``silhouette_edges.vert.glsl``:
    one point per edge (its endpoints, the start and length of its run in the face list), the
    face list (indices of an edge's one, two or, non-manifold, more faces, edge after edge) and
    each face's normal. The face list, normals and part poses are buffer textures, not shader
    storage buffers: llvmpipe's storage-buffer load made the edge pass 2.4x slower
    (instancing@1e6 at 512^2, map 1024: 646 against 266 ms; 378 with the poses alone moved), as
    it did the G-buffer pass (``harness.gl.geometry.SceneMesh``).

    Positions are stored relative to ``origin``, the centre of the scene's bounds, and the
    vertex stage works in that frame: :meth:`uniforms` folds ``model`` (the translation to the
    origin) into the light view and brings the light into the frame, in float64. So float32
    never holds a coordinate as large as the scene's distance from the world origin
    (hard_far_from_origin, 1e5 away: over half a texel of error in world coordinates). Each
    edge carries its part, and :meth:`place` uploads each part's rigid motion (moving objects:
    ``Frame.part_poses``) in that frame, which the vertex stage applies to the edge's
    endpoints and to its faces' normals."""

    def __init__(self, adjacency: EdgeAdjacency):
        if len(adjacency.edge_of_half) >= MAX_FACE_REFERENCES:
            raise ValueError(f"{len(adjacency.edge_of_half)} edge-face references: the edge "
                             f"mesh addresses at most {MAX_FACE_REFERENCES}")
        by_edge = np.argsort(adjacency.edge_of_half, kind="stable")
        edge_faces = adjacency.face_of_half[by_edge].astype(np.uint32)
        first = np.cumsum(adjacency.faces_per_edge) - adjacency.faces_per_edge
        self.origin = (adjacency.vertices.min(axis=0) + adjacency.vertices.max(axis=0)) / 2
        local = adjacency.vertices - self.origin
        part = adjacency.part_of_vertex[adjacency.edges[:, 0]]
        points = np.concatenate([local[adjacency.edges].reshape(-1, 6), first[:, None],
                                 adjacency.faces_per_edge[:, None], part[:, None]], axis=1)
        normals = np.zeros((len(adjacency.face_normals), 4), np.float32)
        normals[:, :3] = adjacency.face_normals
        self.edges = VertexArray(points, EDGE_SIZES, mode=GL.GL_POINTS)
        self.parts = int(part.max(initial=0)) + 1
        poses = np.zeros((self.parts * 4, 4), np.float32)
        self.buffer_textures = (BufferTexture(edge_faces, GL.GL_R32UI),
                                BufferTexture(normals, GL.GL_RGBA32F),
                                BufferTexture(poses, GL.GL_RGBA32F, dynamic=True))
        self.place(np.tile(np.eye(4), (self.parts, 1, 1)))

    def place(self, poses: np.ndarray) -> None:
        """Upload each part's rigid transform, ``poses`` (P, 4, 4) in world space, as it acts
        on the mesh's positions relative to ``origin`` (float64, then float32). An identity
        stays exactly one, so a still scene's edges are the ones built."""
        local = poses.copy()
        local[:, :3, 3] += poses[:, :3, :3] @ self.origin - self.origin
        # column-major: four texels per part, one per column of its mat4
        self.buffer_textures[2].write(local.transpose(0, 2, 1).astype(np.float32))

    def uniforms(self, light: Light, light_view: np.ndarray) -> dict:
        """``light_view_model`` (``light_view`` after ``model``), ``light_in_model`` (the
        light as a homogeneous vector, w = 0 directional, in the mesh's frame) and the texture
        units :meth:`draw` binds the buffer textures to."""
        model = np.eye(4)
        model[:3, 3] = self.origin
        light_vector = (np.append(-light.direction, 0.0) if light.type == "directional"
                        else np.append(light.position, 1.0))
        return {"light_view_model": light_view @ model,
                "light_in_model": np.linalg.solve(model, light_vector),
                "edge_faces": EDGE_FACES_UNIT, "face_normals": FACE_NORMALS_UNIT,
                "part_poses": PART_POSES_UNIT}

    def draw(self) -> None:
        for unit, texture in zip((EDGE_FACES_UNIT, FACE_NORMALS_UNIT, PART_POSES_UNIT),
                                 self.buffer_textures):
            texture.bind(unit)
        self.edges.draw()

    def release(self) -> None:
        self.edges.release()
        for texture in self.buffer_textures:
            texture.release()


def project_edges(endpoints: np.ndarray, frustum: LightFrustum,
                  res: int) -> tuple[np.ndarray, np.ndarray]:
    """Map-texel coordinates (E, 2, 2) and light depths (E, 2) of the edges, clipped to the
    near plane (perspective lights); edges wholly behind it are dropped."""
    view = endpoints @ frustum.view[:3, :3].T + frustum.view[:3, 3]
    depth = -view[..., 2]
    near = frustum.near
    behind = depth < near
    view, depth = view[~behind.all(axis=1)], depth[~behind.all(axis=1)]
    for end in (0, 1):
        clip = depth[:, end] < near
        other = 1 - end
        t = (near - depth[clip, end]) / (depth[clip, other] - depth[clip, end])
        view[clip, end] += t[:, None] * (view[clip, other] - view[clip, end])
        depth[clip, end] = near
    clip = np.concatenate([view, np.ones(view.shape[:-1] + (1,))], axis=-1) @ frustum.proj.T
    ndc = clip[..., :2] / clip[..., 3:4]
    return (ndc * 0.5 + 0.5) * res, depth


def edge_quads(texel: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Two triangles per edge (E * 6 vertices of VERTEX_FLOATS floats): the segment widened
    perpendicular and lengthened at both ends by QUAD_HALF_WIDTH texels, each vertex carrying
    both endpoints and their depths for the fragment shader."""
    a, b = texel[:, 0], texel[:, 1]
    along = b - a
    length = np.linalg.norm(along, axis=1, keepdims=True)
    # an edge seen end-on from the light projects to a point: any direction covers it
    along = np.where(length > 1e-9, along / np.maximum(length, 1e-9), [1.0, 0.0])
    across = np.stack([-along[:, 1], along[:, 0]], axis=1)
    e = QUAD_HALF_WIDTH
    corners = np.stack([a - e * along - e * across, b + e * along - e * across,
                        b + e * along + e * across, a - e * along + e * across], axis=1)
    triangles = corners[:, [0, 1, 2, 0, 2, 3]]
    per_edge = np.concatenate([a, b, depth], axis=1)
    return np.concatenate([triangles, np.repeat(per_edge[:, None, :], 6, axis=1)],
                          axis=2).astype(np.float32).reshape(-1, VERTEX_FLOATS)
