"""Watertightness of rt's traversal: shadow rays aimed exactly at the vertices and the edges of
a closed tessellated sphere, from outside it towards a point light at its centre, never pass
through. The rays start where the test puts them (G-buffer points written by hand, normals 0:
no origin offset), so each ray's line passes exactly through its vertex, or through the
float32 midpoint of its edge.

Under a directional light straight down, rays up from below a flat mesh at z = 0 keep their
x and y exactly (the origin moves along the normal, +z, only; the watertight test's shear is
0), so their edge functions are those of the points themselves: exactly 0 through the shared
edges and vertices of a grid of integer squares, and rounded to 0 in float32 (while exactly
they say "outside") just beyond a border edge of a tilted square."""

from __future__ import annotations

import numpy as np
import pytest
from OpenGL import GL

from harness import config
from harness.technique import registry
from harness.scene import build_scene
from harness.technique import Frame, reset_gl_state

SIZE = 32  # 1024 rays: 162 vertices and 480 edges of a twice-subdivided icosphere


def sphere_scene(subdivisions: int):
    data = {"resolution": [SIZE, SIZE],
            "camera": {"position": [0, -6, 0], "target": [0, 0, 0], "up": [0, 0, 1]},
            "light": {"type": "point", "position": [0, 0, 0]},
            "objects": [{"shape": "sphere", "radius": 1.0, "subdivisions": subdivisions}]}
    return build_scene("sphere", config.Scene(**data))


def targets(part) -> np.ndarray:
    """Every vertex and the float32 midpoint of every edge of the mesh."""
    faces = part.faces
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]],
                                              faces[:, [2, 0]]]), axis=1), axis=0)
    v = part.vertices.astype(np.float32)
    return np.concatenate([v, (v[edges[:, 0]] + v[edges[:, 1]]) * np.float32(0.5)])


def write_gbuffer(frame: Frame, points: np.ndarray, normal) -> None:
    """G-buffer texels 0 .. N-1 (row by row from the bottom): ``points`` covered, each with
    ``normal`` (one for all, or one per point); the others uncovered."""
    position = np.zeros((SIZE * SIZE, 4), np.float32)
    position[:len(points), :3], position[:len(points), 3] = points, 1.0
    normals = np.zeros_like(position)
    normals[:len(points), :3] = normal
    for texture, data in ((frame.gbuffer.position_texture, position),
                          (frame.gbuffer.normal_texture, normals)):
        GL.glBindTexture(GL.GL_TEXTURE_2D, texture.id)
        GL.glTexSubImage2D(GL.GL_TEXTURE_2D, 0, 0, 0, SIZE, SIZE, GL.GL_RGBA, GL.GL_FLOAT,
                           data.reshape(SIZE, SIZE, 4))
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)


def read_mask(texture) -> np.ndarray:
    out = np.empty((texture.height, texture.width), np.float32)
    GL.glBindTexture(GL.GL_TEXTURE_2D, texture.id)
    GL.glGetTexImage(GL.GL_TEXTURE_2D, 0, GL.GL_RED, GL.GL_FLOAT, out)
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
    return out.ravel()


def traced(scene, points: np.ndarray, normal=(0.0, 0.0, 0.0), build: str = "lbvh") -> np.ndarray:
    """rt's V (0 or 1) of the ray from each of ``points`` (G-buffer texels with ``normal``) on
    ``scene``, its bottom levels built by ``build`` with one triangle per leaf."""
    frame = Frame(scene)
    cls = registry.get("rt")
    technique = cls(cls.Params(build=build, leaf_size=1))
    try:
        technique.prepare(frame)
        technique.update(frame)
        write_gbuffer(frame, points, normal)
        frame.meter.new_frame(True)
        technique.render(frame)
        mask = read_mask(technique.mask)
    finally:
        technique.release()
        reset_gl_state()
        frame.release()
    assert (mask[len(points):] == 1).all()  # uncovered texels: no ray, lit
    return mask[:len(points)]


@pytest.mark.parametrize("build", ["lbvh", "sah"])
def test_rays_at_vertices_and_edges_never_pass_through(build, gl_context):
    """From 2 x each vertex and edge midpoint of a closed icosphere (162 vertices, 480 edges;
    2 x is exact in float32) towards a point light at its centre: every ray meets the sphere
    (V = 0), whatever the builder. Each receiver faces the light (its normal towards the
    centre, along its own ray, so the origin offset keeps the ray on its line): with no normal
    it faces nowhere, no ray is traced, and the test passed with watertight_hit always false.
    Run against the Moller-Trumbore test in float32 (edge tests u >= 0, v >= 0, u + v <= 1
    each rounded on its own; a temporary rt_watertight.glsl) it let 43 of the 642 rays
    through, with both builders."""
    scene = sphere_scene(2)
    points = targets(scene.parts[0])
    assert len(points) == 162 + 480
    towards_light = -points / np.linalg.norm(points, axis=1, keepdims=True)
    through = np.flatnonzero(traced(scene, 2 * points, towards_light, build=build) != 0)
    assert len(through) == 0, f"{len(through)} rays passed through: {points[through][:5]}"


UP = (0.0, 0.0, 1.0)  # the receivers' normal: facing the light straight above them
GRID = 4  # squares along each side of the grid: vertices on x, y = 0 .. GRID


def flat_mesh_scene(folder, obj: str):
    """The OBJ text ``obj`` (a flat mesh at z = 0) under a directional light straight down,
    seen from above (the receivers' normal, +z, is their visible side)."""
    (folder / "m.obj").write_text(obj)
    data = {"resolution": [SIZE, SIZE],
            "camera": {"position": [2, -6, 8], "target": [2, 2, 0], "up": [0, 0, 1]},
            "light": {"type": "directional", "direction": [0, 0, -1]},
            "objects": [{"shape": "mesh", "path": str(folder / "m.obj")}]}
    return build_scene("mesh", config.Scene(**data))


def below(xy) -> np.ndarray:
    """Receivers at z = -1 under the points ``xy``: their rays go straight up through them."""
    xy = np.asarray(xy, np.float32).reshape(-1, 2)
    return np.c_[xy, np.full(len(xy), -1.0, np.float32)]


def grid_obj() -> str:
    """GRID x GRID unit squares, each split along a diagonal, the diagonals alternating (an
    inner vertex is shared by 4 or by 8 triangles)."""
    number = {(x, y): 1 + x * (GRID + 1) + y for x in range(GRID + 1) for y in range(GRID + 1)}
    lines = [f"v {x} {y} 0" for x, y in number]
    for x in range(GRID):
        for y in range(GRID):
            a, b, c, d = (number[p] for p in ((x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)))
            lines += ([f"f {a} {b} {c}", f"f {a} {c} {d}"] if (x + y) % 2 == 0 else
                      [f"f {a} {b} {d}", f"f {b} {c} {d}"])
    return "\n".join(lines) + "\n"


def shared_points() -> np.ndarray:
    """Every inner vertex of the grid, and 1/4, 1/2 and 3/4 along every inner edge (the sides
    between squares and the diagonals): exact in float32, so their edge functions are 0."""
    inner = np.arange(1, GRID)
    along = (np.arange(GRID)[:, None] + [0.25, 0.5, 0.75]).ravel()
    vertices = [(x, y) for x in inner for y in inner]
    sides = [(x, y) for x in inner for y in along] + [(x, y) for y in inner for x in along]
    diagonals = [(x + t, y + (t if (x + y) % 2 == 0 else 1 - t))
                 for x in range(GRID) for y in range(GRID) for t in (0.25, 0.5, 0.75)]
    return np.array(vertices + sides + diagonals, np.float32)


@pytest.mark.parametrize("build", ["lbvh", "sah"])
def test_rays_through_a_grids_shared_edges_and_vertices_are_all_shadowed(build, tmp_path,
                                                                         monkeypatch, gl_context):
    """Straight up through each inner vertex and edge of the grid (9 vertices, 120 points on
    edges): every ray meets a triangle (V = 0), whatever the builder. Beside the grid, rays are
    lit: they are traced (a receiver whose normal does not face the light gets V = 0 and no
    ray). Catches an edge function of exactly 0 counted as outside (``<=`` for ``<`` in
    rt_watertight.glsl's test): every one of these rays passed through."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    scene = flat_mesh_scene(tmp_path, grid_obj())
    shared = shared_points()
    assert len(shared) == 9 + 120
    beside = [(-0.5, 2), (GRID + 0.5, 2), (2, -0.5), (2, GRID + 0.5)]
    v = traced(scene, below(np.r_[shared, beside]), UP, build)
    through = np.flatnonzero(v[:len(shared)] != 0)
    assert len(through) == 0, f"{len(through)} rays passed through: {shared[through][:5]}"
    assert (v[len(shared):] == 1).all()


# an open square with integer corners, its border edge from (0, 0) to (5, 2) along no axis
TILTED_SQUARE_OBJ = "v 0 0 0\nv 5 2 0\nv 3 7 0\nv -2 5 0\nf 1 2 3\nf 1 3 4\n"


def beside_the_border_edge(side: int) -> np.ndarray:
    """The float32 points nearest the line y = 0.4 x through the border edge (0, 0) - (5, 2), on
    its ``side`` (1: beyond it, 2x - 5y > 0; -1: inside), for x = 2.51, 2.52, .. 3.5 rounded to
    float32 (many bits: products that round)."""

    def sign(x, y):  # of 2x - 5y, exact in float64 for float32 x, y
        return np.sign(2 * x.astype(np.float64) - 5 * y.astype(np.float64))

    x = (2.5 + np.arange(1, 101) / 100).astype(np.float32)
    nearest = (0.4 * x.astype(np.float64)).astype(np.float32)
    y = np.where(sign(x, nearest) == side, nearest,
                 np.nextafter(nearest, -side * np.float32(np.inf)))
    assert (sign(x, y) == side).all()
    return np.c_[x, y]


def border_edge_function(xy: np.ndarray, dtype) -> np.ndarray:
    """rt_watertight.glsl's W of the triangle (0, 0), (5, 2), (3, 7) for rays straight up from
    ``xy``: Bx Ay - By Ax, A and B the edge's ends less the origin in float32 (as the shader
    subtracts), the products and their difference in ``dtype``: float32, each product rounded
    (as llvmpipe evaluates it: no fused multiply-add), or float64, exact in sign (the
    shader's fallback: products of float32 numbers are exact in float64)."""
    a = (np.float32(0) - xy).astype(dtype)
    b = (np.array([5, 2], np.float32) - xy).astype(dtype)
    return b[:, 0] * a[:, 1] - b[:, 1] * a[:, 0]


def test_rays_a_rounding_beyond_a_border_edge_are_lit(tmp_path, monkeypatch, gl_context):
    """Straight up from the float32 points nearest a tilted square's border edge: those just
    beyond it are lit, those just inside shadowed. The shader's exact W says the side the
    points are on (x and 0.4 x lie within a factor 2 of the ends' 5 and 2, so its subtractions
    are exact), and for 9 of the 100 beyond the edge its float32 W rounds to 0: the test's
    double-precision fallback decides them. Catches the fallback dropped (the float32 zero read
    as on the edge: those 9 rays shadowed)."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    scene = flat_mesh_scene(tmp_path, TILTED_SQUARE_OBJ)
    beyond, inside = beside_the_border_edge(1), beside_the_border_edge(-1)
    assert (border_edge_function(beyond, np.float64) > 0).all()
    assert (border_edge_function(inside, np.float64) < 0).all()
    assert (border_edge_function(beyond, np.float32) == 0).sum() == 9
    v = traced(scene, below(np.r_[beyond, inside]), UP)
    shadowed = np.flatnonzero(v[:len(beyond)] != 1)
    assert len(shadowed) == 0, f"{len(shadowed)} rays beyond the edge shadowed: " \
                               f"{beyond[shadowed][:5]}"
    assert (v[len(beyond):] == 0).all()
