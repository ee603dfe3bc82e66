"""The GPU side of a virtual shadow map: the page table, the physical pool with its free ring,
and the passes that mark, allocate, cull and draw pages (their shaders say what each does)."""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from OpenGL import GL

from harness.gl.shaders import ComputeProgram, Program
from harness.technique import Frame
from techniques.common.light_maps import count_alpha_tests

from .levels import Levels

HERE = Path(__file__).parent
# vsm_pages.comp.glsl's counters
NEED, RELEASE, HEAD, TAIL, MARKED, ALLOCATED, JOBS, HITS, COMMANDS, INVALIDATED = range(10)
COUNTERS = 10
STAGES = {"count": 0, "release": 1, "allocate": 2, "invalidate": 3}
MAX_BOXES = 32  # vsm_pages.comp.glsl's
# A cluster: this many consecutive triangles at least; at most MAX_CLUSTERS clusters (larger
# ones past it), so culling a page against every cluster stays a small pass.
CLUSTER_TRIANGLES = 64
MAX_CLUSTERS = 512
_LEVEL_DTYPE = np.dtype([("view", "<f4", (16,)), ("proj", "<f4", (16,)), ("grid", "<i4", (4,)),
                         ("res", "<f4", (4,))])
EMPTY_ENTRY = np.array([-1, 0, 0, 0], np.int32)


def pool_tiles(pool_pages: int) -> int:
    """Tiles per row (and rows) of the square pool texture holding ``pool_pages`` tiles."""
    return math.isqrt(pool_pages - 1) + 1


def spatial_order(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The faces in Morton (Z-curve) order of their centroids over the mesh's box, 10 bits per
    axis: consecutive triangles lie close together, so a cluster's box is small. In scene order
    a grid's cluster is a strip across the whole grid, which met every page of its row (a
    tessellated ground drew each cluster into most pages)."""
    if not len(faces):
        return faces
    centroids = vertices[faces].astype(np.float64).mean(axis=1)
    low, high = centroids.min(axis=0), centroids.max(axis=0)
    cells = ((centroids - low) / np.maximum(high - low, 1e-30) * 1023).astype(np.uint64)
    code = np.zeros(len(faces), np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return faces[np.argsort(code, kind="stable")]


def clustering(triangles: int) -> tuple[int, int]:
    """(clusters, triangles per cluster) of a scene of ``triangles``."""
    per = max(CLUSTER_TRIANGLES, -(-triangles // MAX_CLUSTERS))
    return max(1, -(-triangles // per)), per


class Buffer:
    """A shader storage buffer of ``nbytes``."""

    def __init__(self, nbytes: int, data: np.ndarray | None = None):
        self.nbytes = max(int(nbytes), 16)
        self.id = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.id)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, self.nbytes, data, GL.GL_DYNAMIC_DRAW)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)

    def bind(self, binding: int) -> None:
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, binding, self.id)

    def write(self, data: np.ndarray, offset: int = 0) -> None:
        data = np.ascontiguousarray(data)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.id)
        GL.glBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, offset, data.nbytes, data)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)

    def fill(self, value: np.ndarray) -> None:
        """Every element set to ``value`` (4 or 16 bytes)."""
        fmt = {4: (GL.GL_R32UI, GL.GL_RED_INTEGER), 16: (GL.GL_RGBA32UI, GL.GL_RGBA_INTEGER)}
        internal, pixel = fmt[value.nbytes]
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.id)
        GL.glClearBufferData(GL.GL_SHADER_STORAGE_BUFFER, internal, pixel, GL.GL_UNSIGNED_INT,
                             value.view(np.uint32))
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)

    def read(self, dtype, count: int) -> np.ndarray:
        GL.glMemoryBarrier(GL.GL_BUFFER_UPDATE_BARRIER_BIT)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.id)
        size = np.dtype(dtype).itemsize * count
        out = np.asarray(GL.glGetBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, size))
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        return out.view(dtype)[:count].copy()

    def release(self) -> None:
        GL.glDeleteBuffers(1, [self.id])


@dataclass
class FrameCounts:
    """What one frame's allocation did (the run's ``extra`` columns)."""

    marked: int = 0
    allocated: int = 0
    rendered: int = 0
    hits: int = 0
    coarsened: int = 0  # levels every pixel was moved up by to fit the pool
    slant_floor: float = 0.25  # the receiver's slant's floor the pool held (levels.SLANT_FLOORS)
    draws: int = 0  # cluster draws into tiles
    invalidated: int = 0


def barrier() -> None:
    """After a pass: its writes visible to every later read. No program stays current: Mesa 22
    (llvmpipe) never deleted a program used after a compute program had been current."""
    GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT | GL.GL_SHADER_IMAGE_ACCESS_BARRIER_BIT
                       | GL.GL_TEXTURE_FETCH_BARRIER_BIT | GL.GL_COMMAND_BARRIER_BIT)
    GL.glUseProgram(0)


class PagePool:
    """The page table for ``table_size`` entries, a pool of ``pool_pages`` tiles of ``page``
    texels, the scene's ``faces`` (indices into its vertex buffer, in :func:`spatial_order`)
    cut into clusters, and the passes over them. With ``cutouts`` (a scene with alpha-tested
    casters: ``faces`` index the scene mesh's cut-out corners) the page draws discard cut-out
    texels."""

    def __init__(self, pool_pages: int, page: int, table_size: int, level_count: int,
                 faces: np.ndarray, cutouts: bool = False):
        self.pool_pages, self.page, self.table_size = pool_pages, page, table_size
        self.tiles = pool_tiles(pool_pages)
        self.pool_res = self.tiles * page
        self.pool = GL.glGenTextures(1)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.pool)
        GL.glTexStorage2D(GL.GL_TEXTURE_2D, 1, GL.GL_DEPTH_COMPONENT32F, self.pool_res,
                          self.pool_res)
        for name in (GL.GL_TEXTURE_MIN_FILTER, GL.GL_TEXTURE_MAG_FILTER):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, name, GL.GL_NEAREST)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        self.fbo = GL.glGenFramebuffers(1)  # the pool is its depth, nothing else
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.fbo)
        GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_TEXTURE_2D,
                                  self.pool, 0)
        GL.glDrawBuffer(GL.GL_NONE)
        GL.glReadBuffer(GL.GL_NONE)
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"page pool framebuffer incomplete: 0x{status:x}")
        self.levels = Buffer(level_count * _LEVEL_DTYPE.itemsize)
        self.entries = Buffer(table_size * 16)
        self.requests = Buffer(table_size * 4)
        self.counters = Buffer(COUNTERS * 4)
        self.free = Buffer(pool_pages * 4)
        self.jobs = Buffer(pool_pages * 16)
        self.clusters, self.cluster_triangles = clustering(len(faces))
        self.triangles = len(faces)
        self.indices = Buffer(faces.nbytes, np.ascontiguousarray(faces, np.uint32))
        self.vao = GL.glGenVertexArrays(1)
        self.geometry = None  # the scene mesh whose vertex buffer the VAO reads
        self.bounds = Buffer(self.clusters * 32)
        self.capacity = pool_pages * self.clusters
        self.commands = Buffer(self.capacity * 20)
        self.programs = {stage: ComputeProgram(HERE / "vsm_pages.comp.glsl", {"STAGE": number})
                         for stage, number in STAGES.items()}
        self.cull = ComputeProgram(HERE / "vsm_cull.comp.glsl")
        self.clear_tiles = Program(HERE / "vsm_clear.vert.glsl", HERE / "vsm_page.frag.glsl")
        self.cluster_bounds = ComputeProgram(HERE / "vsm_bounds.comp.glsl")
        self.cutouts = {"ALPHA_TEST": 1} if cutouts else {}
        self.draw = Program(HERE / "vsm_page.vert.glsl", HERE / "vsm_page.frag.glsl",
                            self.cutouts)
        self.counting = None  # the page draws counting their alpha tests, made when needed
        self.empty_vao = GL.glGenVertexArrays(1)
        self.reset()

    @property
    def mem_bytes(self) -> int:
        """The pool and the tables (entries, requests, free ring)."""
        return self.pool_res ** 2 * 4 + self.table_size * 20 + self.pool_pages * 4

    def reset(self) -> None:
        """Every tile free, no page held."""
        self.entries.fill(EMPTY_ENTRY)
        self.free.write(np.arange(self.pool_pages, dtype=np.int32))
        counters = np.zeros(COUNTERS, np.uint32)
        counters[TAIL] = self.pool_pages
        self.counters.write(counters)

    def bind(self) -> None:
        for binding, buffer in enumerate((self.levels, self.entries, self.requests, self.counters,
                                          self.free, self.jobs)):
            buffer.bind(binding)
        self.bounds.bind(8)
        self.commands.bind(9)

    def upload_levels(self, levels: Levels) -> None:
        data = np.zeros(levels.count, _LEVEL_DTYPE)
        data["view"] = levels.views.transpose(0, 2, 1).reshape(-1, 16)  # column-major
        data["proj"] = levels.projs.transpose(0, 2, 1).reshape(-1, 16)
        data["grid"] = np.c_[levels.origins, levels.pages, levels.bases]
        data["res"][:, 0] = levels.res
        self.levels.write(data)

    def _stage(self, stage: str, **uniforms) -> None:
        self.bind()
        self.programs[stage].use().set(table_size=self.table_size, pool_pages=self.pool_pages,
                                       **uniforms)
        GL.glDispatchCompute(-(-self.table_size // 64), 1, 1)
        barrier()

    def counts(self) -> np.ndarray:
        return self.counters.read(np.uint32, COUNTERS)

    def start_frame(self) -> None:
        """Zero the frame's counters (the free ring's head and tail stay)."""
        counters = self.counts()
        kept = np.zeros(COUNTERS, np.uint32)
        kept[[HEAD, TAIL]] = counters[[HEAD, TAIL]]
        self.counters.write(kept)
        self.requests.fill(np.zeros(1, np.uint32))

    def fits(self, level_uniforms: dict) -> tuple[bool, np.ndarray]:
        """Whether the requests fit the pool (the count pass)."""
        self._stage("count", **level_uniforms)
        c = self.counts()
        free = int(c[TAIL]) - int(c[HEAD])
        return int(c[NEED]) <= free + int(c[RELEASE]), c

    def allocate(self, level_uniforms: dict) -> np.ndarray:
        """Release the unrequested pages' tiles, give the requested ones theirs, list the jobs;
        the counters after it."""
        self._stage("release", **level_uniforms)
        self._stage("allocate", **level_uniforms)
        return self.counts()

    def invalidate(self, level_uniforms: dict, everything: bool,
                   boxes: list[tuple[np.ndarray, np.ndarray]]) -> int:
        """Pages whose box meets one of ``boxes`` (world low, high), or all, lose their depths;
        how many did."""
        uniforms = {}
        for b, (low, high) in enumerate(boxes[:MAX_BOXES]):
            uniforms[f"box_low[{b}]"], uniforms[f"box_high[{b}]"] = low, high
        everything = everything or len(boxes) > MAX_BOXES
        before = int(self.counts()[INVALIDATED])
        self._stage("invalidate", invalidate_all=everything, boxes=min(len(boxes), MAX_BOXES),
                    **uniforms, **level_uniforms)
        return int(self.counts()[INVALIDATED]) - before

    def box_clusters(self, frame: Frame) -> None:
        """The caster clusters' boxes from the scene's vertex buffer as it is now (the VAO of
        the page draws reads it too)."""
        # by the mesh, not its buffer's name: a name freed and given again is another buffer
        if self.geometry is not frame.geometry:
            GL.glBindVertexArray(self.vao)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, frame.geometry.vbo)
            GL.glEnableVertexAttribArray(0)
            GL.glVertexAttribPointer(0, 3, GL.GL_FLOAT, GL.GL_FALSE, 12, ctypes.c_void_p(0))
            if self.cutouts:  # each corner's (u, v, mask), as the scene mesh draws it
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, frame.geometry.cutout_vbo)
                GL.glEnableVertexAttribArray(1)
                GL.glVertexAttribPointer(1, 3, GL.GL_FLOAT, GL.GL_FALSE, 12,
                                         ctypes.c_void_p(0))
            GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, self.indices.id)
            GL.glBindVertexArray(0)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
            self.geometry = frame.geometry
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 6, frame.geometry.vbo)
        self.indices.bind(7)
        self.bounds.bind(8)
        self.cluster_bounds.use().set(clusters=self.clusters,
                                      cluster_triangles=self.cluster_triangles,
                                      triangles=self.triangles)
        GL.glDispatchCompute(-(-self.clusters // 64), 1, 1)
        barrier()

    def render_jobs(self, frame: Frame, jobs: int, level_uniforms: dict) -> int:
        """Empty the jobs' tiles, cull the clusters per job, draw them into the tiles; the
        number of cluster draws."""
        if jobs == 0:
            return 0
        self.bind()
        self.cull.use().set(clusters=self.clusters, cluster_triangles=self.cluster_triangles,
                            triangles=self.triangles, capacity=np.uint32(self.capacity),
                            **level_uniforms)
        GL.glDispatchCompute(-(-self.clusters // 64), jobs, 1)
        barrier()
        draws = min(int(self.counts()[COMMANDS]), self.capacity)
        self._draw_jobs(frame, self.draw, jobs, draws, level_uniforms)
        return draws

    def alpha_tests(self, frame: Frame, jobs: int, draws: int, level_uniforms: dict) -> int:
        """The alpha tests of the last :meth:`render_jobs` (its ``jobs`` and ``draws``),
        counted by drawing the same tiles again with a counting program (the same depths):
        untimed, as the shared depth pass counts its own. 0 without cut-outs."""
        if not self.cutouts or draws == 0:
            return 0
        if self.counting is None:
            self.counting = Program(HERE / "vsm_page.vert.glsl", HERE / "vsm_page.frag.glsl",
                                    {**self.cutouts, "COUNT_ALPHA_TESTS": 1})
        self.bind()  # the jobs and levels the page draws read
        return count_alpha_tests(
            lambda: self._draw_jobs(frame, self.counting, jobs, draws, level_uniforms))

    def _draw_jobs(self, frame: Frame, program: Program, jobs: int, draws: int,
                   level_uniforms: dict) -> None:
        """Empty the jobs' tiles and draw the culled clusters (``draws`` commands) into them
        with ``program``."""
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.fbo)
        GL.glViewport(0, 0, self.pool_res, self.pool_res)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_ALWAYS)  # the jobs' tiles to the far plane
        self.clear_tiles.use().set(page_size=self.page, pool_tiles=self.tiles,
                                   pool_res=float(self.pool_res))
        GL.glBindVertexArray(self.empty_vao)
        GL.glDrawArraysInstanced(GL.GL_TRIANGLE_STRIP, 0, 4, jobs)
        GL.glDepthFunc(GL.GL_LESS)
        for plane in range(4):
            GL.glEnable(GL.GL_CLIP_DISTANCE0 + plane)
        program.use().set(pool_tiles=self.tiles, pool_res=float(self.pool_res),
                          **level_uniforms)
        frame.bind_alpha(program, 0)
        GL.glBindVertexArray(self.vao)
        GL.glBindBuffer(GL.GL_DRAW_INDIRECT_BUFFER, self.commands.id)
        GL.glMultiDrawElementsIndirect(GL.GL_TRIANGLES, GL.GL_UNSIGNED_INT, ctypes.c_void_p(0),
                                       draws, 0)
        GL.glBindBuffer(GL.GL_DRAW_INDIRECT_BUFFER, 0)
        GL.glBindVertexArray(0)
        for plane in range(4):
            GL.glDisable(GL.GL_CLIP_DISTANCE0 + plane)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        barrier()

    def table(self) -> np.ndarray:
        """The entries (table_size, 4) int32: slot, global x, y, valid (tests, diagnostics)."""
        return self.entries.read(np.int32, self.table_size * 4).reshape(-1, 4)

    def requested(self) -> np.ndarray:
        return self.requests.read(np.uint32, self.table_size)

    def release(self) -> None:
        for buffer in (self.levels, self.entries, self.requests, self.counters, self.free,
                       self.jobs, self.bounds, self.commands, self.indices):
            buffer.release()
        for program in (*self.programs.values(), self.cull, self.clear_tiles,
                        self.cluster_bounds, self.draw, self.counting):
            if program is not None:
                program.release()
        GL.glDeleteTextures([self.pool])
        GL.glDeleteVertexArrays(2, [self.empty_vao, self.vao])
        GL.glDeleteFramebuffers(1, [self.fbo])
