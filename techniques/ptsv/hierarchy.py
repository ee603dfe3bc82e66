"""The GPU side of ptsv: the hierarchy over the view samples, the casters' volumes (a
triangle's or a quad's, casters.py) and the level-by-level traversal, with the buffers they
share (a helper of the technique, not one).

Levels: level 0 is the samples (the G-buffer at the mask's resolution), level k >= 1 a grid of
nodes, each the ``tile`` x ``tile`` nodes (or samples) below it, up to a single root. With
clusters (``slices`` > 1, Sintorn et al. 2014) each level holds that grid once per depth slice
(a node bounds only its slice's samples: a cluster at level 1), and one root above the top
level's slices. Node numbers run level 1 first, slice-major within a level; the marks buffer
holds one flag per sample, then one per node. A node's box (min, max) carries in its fourth
lane the bits of its children that are not empty (at level 1, its samples), so that the
traversal visits those only. The traversal queues (volume, node) items in two regions used in
turn (level k in region k & 1), each of ``capacity`` items; the planes buffer holds the queued
casters' volumes. A volume whose footprint on the screen at most 2 x 2 nodes of
a lower level cover starts there (ptsv_setup.comp.glsl): its (volume, slice) seeds, sorted by
level (counted, then placed), are tested just before their level's traversal
(ptsv_seed.comp.glsl). The queues, planes and seeds grow when a frame overflows them (counted
on the GPU, read back once after the traversal, which then runs again with room): memory follows
the scene instead of a worst case.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from OpenGL import GL

from harness.gl.framebuffer import Texture
from harness.gl.shaders import ComputeProgram

HERE = Path(__file__).parent
# counters (ptsv_volume.glsl's COUNT_*), then one per level: items queued for it
# the harness's traversal columns: traversal_nodes the node-volume tests, triangle_tests the
# sample-volume tests (each of one caster's volume against one view sample); triangles_culled
# counts a culled quad's two triangles
COUNTER_NAMES = ("volumes_queued", "triangles_culled", "traversal_nodes", "trivial_accepts",
                 "root_accepts", "triangle_tests", "volumes_seeded")
COUNT_LEVELS = 8
EDGE_ON = 1e-12  # |cos| between a triangle's normal and the light below which it casts nothing
MIN_CAPACITY = 1 << 14
MAX_CAPACITY = 1 << 22  # items per queue region (32 MiB): past it, the casters go in batches
ITEM_BYTES = 8  # (volume, node)
PLANES_BYTES = 96  # six vec4 per volume: five planes, its bounds across the light
START_BYTES = 16  # per volume: its start level, the nodes' ranges there (ptsv_setup.comp.glsl)
SEED_BYTES = 8  # (volume, slice) per depth slice of a volume's start (ptsv_seed.comp.glsl)
BOX_BYTES = 32
NORMAL_UNIT = 8  # the G-buffer's normals, for the box pass (past TEXELS' units)
CASTER_BYTES = 20  # four corner indices and the closed part's side


def closed_sides(triangles: np.ndarray, part_faces: list[int], closed: np.ndarray) -> np.ndarray:
    """Per triangle (T, 3, 3): 0 in an open part; in a closed part 1 where the part's winding
    turns its faces outward (positive signed volume), -1 where inward."""
    tri = triangles.astype(np.float64)
    det = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    starts = np.minimum(np.concatenate([[0], np.cumsum(part_faces)[:-1]]), max(len(det) - 1, 0))
    volume = np.add.reduceat(det, starts) if len(det) else np.zeros(0)
    volume = np.where(np.asarray(part_faces) > 0, volume, 0.0)
    side = np.where(closed, np.sign(volume), 0).astype(np.int32)
    return np.repeat(side, part_faces)


def level_sizes(width: int, height: int, tile: int) -> list[tuple[int, int]]:
    """Samples per row and column, then nodes per row and column of each level up to the root
    (at least one node level)."""
    sizes = [(width, height)]
    while len(sizes) < 2 or sizes[-1] != (1, 1):
        w, h = sizes[-1]
        sizes.append((-(-w // tile), -(-h // tile)))
    return sizes


def _storage(nbytes: int) -> int:
    buffer = GL.glGenBuffers(1)
    GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, buffer)
    GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, max(int(nbytes), 16), None, GL.GL_DYNAMIC_COPY)
    GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
    return buffer


def _upload(data: np.ndarray) -> int:
    """A storage buffer holding ``data``."""
    data = np.ascontiguousarray(data)
    buffer = _storage(data.nbytes)
    GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, buffer)
    GL.glBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, data.nbytes, data)
    GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
    return buffer


def _zero(buffer: int) -> None:
    GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, buffer)
    GL.glClearBufferData(GL.GL_SHADER_STORAGE_BUFFER, GL.GL_R32UI, GL.GL_RED_INTEGER,
                         GL.GL_UNSIGNED_INT, None)
    GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)


def _set(program, **uniforms) -> None:
    """Unsigned uniforms: ints as ``uint``, pairs as ``uvec2``; the rest through Program.set."""
    rest = {}
    for name, value in uniforms.items():
        if isinstance(value, tuple) and all(isinstance(v, (int, np.integer)) for v in value):
            GL.glUniform2ui(program.location(name), *map(int, value))
        elif isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            GL.glUniform1ui(program.location(name), int(value))
        else:
            rest[name] = value
    program.set(**rest)


def _barrier() -> None:
    GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT | GL.GL_COMMAND_BARRIER_BIT
                       | GL.GL_TEXTURE_FETCH_BARRIER_BIT)


# The buffer textures over the storage buffers through which the traversal reads them (llvmpipe
# loads a storage buffer's vector lane by lane, a texel in one fetch): sampler uniform ->
# (texture unit, texel format, bytes a texel).
TEXELS = {"box_texels": (1, GL.GL_RGBA32F, 16), "plane_texels": (2, GL.GL_RGBA32F, 16),
          "item_texels": (3, GL.GL_RG32UI, 8), "mark_texels": (4, GL.GL_R32UI, 4),
          "slice_texels": (5, GL.GL_R32UI, 4), "vertex_texels": (6, GL.GL_RGB32F, 12),
          "caster_texels": (7, GL.GL_RGBA32UI, 16)}


TEXEL_UNITS = {name: unit for name, (unit, _, _) in TEXELS.items()}  # the samplers' uniforms


def _texels(texture: int, name: str, buffer: int, nbytes: int) -> None:
    """Make ``texture`` the buffer texture ``name`` (TEXELS) over storage ``buffer``."""
    _, texel_format, texel_bytes = TEXELS[name]
    if max(nbytes, 16) // texel_bytes > int(GL.glGetIntegerv(GL.GL_MAX_TEXTURE_BUFFER_SIZE)):
        raise ValueError(f"ptsv: {nbytes} bytes, over the driver's buffer-texture size")
    GL.glBindTexture(GL.GL_TEXTURE_BUFFER, texture)
    GL.glTexBuffer(GL.GL_TEXTURE_BUFFER, texel_format, buffer)
    GL.glBindTexture(GL.GL_TEXTURE_BUFFER, 0)


def _across(light: np.ndarray, axis: np.ndarray, origin: np.ndarray) -> dict:
    """The uniforms of the volumes' cross-section bounds (ptsv_volume.glsl): ``light_u``,
    ``light_v``, two unit axes across ``axis``; for a spot or point light (``light`` (position,
    1)) also ``light_axis``, the unit axis, and ``light_point``, the position relative to
    ``origin``."""
    d = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    u = np.cross(d, np.eye(3)[np.argmin(np.abs(d))])
    u /= np.linalg.norm(u)
    out = {"light_u": u.astype(np.float32), "light_v": np.cross(d, u).astype(np.float32)}
    if light[3] != 0:
        out.update(light_axis=d.astype(np.float32),
                   light_point=(np.asarray(light[:3], np.float64) - origin).astype(np.float32))
    return out


def _rows(groups: int) -> tuple[int, int]:
    """``groups`` work groups as rows of at most 65535 (GL's smallest maximum)."""
    rows = max(1, -(-groups // 65535))
    return -(-groups // rows), rows


class SampleHierarchy:
    """Buffers and programs for one image size, tile, mask divisor, number of depth slices
    (1: tiles) and kind of light (``positional``: a spot or point light, whose programs are
    compiled with POSITIONAL_LIGHT)."""

    def __init__(self, width: int, height: int, divisor: int, tile: int, casters: np.ndarray,
                 closed_side: np.ndarray, slices: int = 1, positional: bool = False):
        self.divisor, self.tile, self.slices = divisor, tile, slices
        self.caster_count = len(casters)
        self.sizes = level_sizes(-(-width // divisor), -(-height // divisor), tile)
        self.levels = len(self.sizes) - 1
        self.samples = self.sizes[0][0] * self.sizes[0][1]
        nodes = [w * h * slices for w, h in self.sizes[1:]]
        self.node_first = [0, *np.cumsum([0] + nodes).tolist()]  # by level, [0] unused
        # tiles: the top level's one node; clusters: one more node over the top level's slices
        self.root = self.node_first[self.levels] if slices == 1 else self.node_first[-1]
        self.nodes = self.root + 1
        self.items_per_group = 64  # the traversal's: one invocation per queued item
        defines = {"TILE": tile, "GROUP_SIZE": self.items_per_group, "EDGE_ON": repr(EDGE_ON),
                   "LEVELS": f"{self.levels}u",
                   **({"POSITIONAL_LIGHT": 1} if positional else {})}

        def program(name, **more):
            return ComputeProgram(HERE / name, {**defines, **more})

        # per kind of box dispatch: level 1 (samples), the levels above, the root over slices
        self.box_programs = {
            "samples": program("ptsv_boxes.comp.glsl", SAMPLES=1,
                               **({"CLUSTERS": 1} if slices > 1 else {})),
            "nodes": program("ptsv_boxes.comp.glsl"),
            **({"merge": program("ptsv_boxes.comp.glsl", MERGE_SLICES=1)} if slices > 1 else {})}
        self.dispatch_program = program("ptsv_dispatch.comp.glsl")
        # the timed programs, and the same counting their work for the untimed repeat
        self.setup_programs = {c: program("ptsv_setup.comp.glsl", **({"COUNT": 1} if c else {}))
                               for c in (False, True)}
        self.seed_programs = {c: program("ptsv_seed.comp.glsl", **({"COUNT": 1} if c else {}))
                              for c in (False, True)}
        self.seed_offsets = program("ptsv_seed.comp.glsl", OFFSETS=1)
        self.seed_scatter = program("ptsv_seed.comp.glsl", SCATTER=1)
        # per (counting, level 1): level 1 tests samples, the levels above nodes
        self.traverse_programs = {(c, leaf): program("ptsv_traverse.comp.glsl",
                                                     **({"COUNT": 1} if c else {}),
                                                     **({"LEAF": 1} if leaf else {}))
                                  for c in (False, True) for leaf in (False, True)}
        self.boxes = _storage(self.nodes * BOX_BYTES)
        self.textures = dict(zip(TEXELS, GL.glGenTextures(len(TEXELS))))
        self.marks = _storage((self.samples + self.nodes) * 4)
        self.counter_count = COUNT_LEVELS + 3 * (self.levels + 1)
        self.counters = _storage(self.counter_count * 4)
        self.dispatch = _storage(12)
        self.sample_slices = _storage(self.samples * 4 if slices > 1 else 0)
        for name, buffer, nbytes in (("box_texels", self.boxes, self.nodes * BOX_BYTES),
                                     ("mark_texels", self.marks, (self.samples + self.nodes) * 4),
                                     ("slice_texels", self.sample_slices,
                                      self.samples * 4 if slices > 1 else 0)):
            _texels(self.textures[name], name, buffer, nbytes)
        # ptsv_setup.comp.glsl's, per caster
        self.closed_side = _upload(np.asarray(closed_side, np.int32))
        self.casters = _upload(np.asarray(casters, np.uint32))
        _texels(self.textures["caster_texels"], "caster_texels", self.casters, casters.nbytes)
        self.capacity = self.volume_capacity = 0
        self.queues = self.planes = self.starts = self.seeds = None
        self.seed_capacity = 0
        self.seed_counts = COUNT_LEVELS + self.levels + 1  # counters' index of level 0's seeds
        first_capacity = max(MIN_CAPACITY, min(self.caster_count, 1 << 20))
        self._grow_seeds(first_capacity)
        self._grow(first_capacity,
                   max(MIN_CAPACITY, min(self.caster_count // 4, MAX_CAPACITY)))
        self.batch = self.caster_count  # casters per traversal batch, halved while queues overflow

    @property
    def mem_bytes(self) -> int:
        """What the hierarchy, marks, volumes and work queues hold."""
        return (self.nodes * BOX_BYTES + (self.samples + self.nodes) * 4
                + (self.samples * 4 if self.slices > 1 else 0)
                + 2 * self.capacity * ITEM_BYTES
                + self.volume_capacity * (PLANES_BYTES + START_BYTES)
                + self.seed_capacity * SEED_BYTES
                + self.counter_count * 4 + 12 + CASTER_BYTES * self.caster_count)

    def _grow(self, capacity: int, volume_capacity: int) -> None:
        if capacity > self.capacity:
            if self.queues:
                GL.glDeleteBuffers(1, [self.queues])
            self.capacity = capacity
            self.queues = _storage(2 * capacity * ITEM_BYTES)
            _texels(self.textures["item_texels"], "item_texels", self.queues,
                    2 * capacity * ITEM_BYTES)
        if volume_capacity > self.volume_capacity:
            if self.planes:
                GL.glDeleteBuffers(1, [self.planes])
            self.volume_capacity = volume_capacity
            if self.starts:
                GL.glDeleteBuffers(1, [self.starts])
            self.starts = _storage(volume_capacity * START_BYTES)
            self.planes = _storage(volume_capacity * PLANES_BYTES)
            _texels(self.textures["plane_texels"], "plane_texels", self.planes,
                    volume_capacity * PLANES_BYTES)

    def _grow_seeds(self, capacity: int) -> None:
        if self.seeds:
            GL.glDeleteBuffers(1, [self.seeds])
        self.seed_capacity = capacity
        self.seeds = _storage(capacity * SEED_BYTES)

    def _bind(self) -> None:
        for name, texture in self.textures.items():
            GL.glActiveTexture(GL.GL_TEXTURE0 + TEXELS[name][0])
            GL.glBindTexture(GL.GL_TEXTURE_BUFFER, texture)
        GL.glActiveTexture(GL.GL_TEXTURE0)
        for binding, buffer in ((2, self.planes), (3, self.boxes), (4, self.marks),
                                (5, self.queues), (6, self.counters), (9, self.sample_slices),
                                (10, self.starts), (11, self.seeds)):
            GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, binding, buffer)

    def bind_marks(self, program) -> None:
        """Bind the marks and the samples' slices as ``program``'s ``mark_texels`` and
        ``slice_texels`` (their TEXELS units)."""
        for name in ("mark_texels", "slice_texels"):
            GL.glActiveTexture(GL.GL_TEXTURE0 + TEXELS[name][0])
            GL.glBindTexture(GL.GL_TEXTURE_BUFFER, self.textures[name])
            program.set(**{name: TEXELS[name][0]})
        GL.glActiveTexture(GL.GL_TEXTURE0)

    def build(self, position: Texture, normal: Texture, origin: np.ndarray,
              depth_plane: np.ndarray, depth_range: tuple[float, float],
              camera_position: np.ndarray, light: np.ndarray) -> None:
        """Each level's node boxes from the G-buffer's positions (relative to ``origin``),
        bottom up; the samples' marks cleared, then set where a covered sample's visible side
        (its ``normal`` turned toward ``camera_position``) faces away from ``light``
        (homogeneous), which is left out of the boxes. With clusters, a sample's slice is its
        view depth (``depth_plane`` . (p, 1), p relative to ``origin``) on a log scale over
        ``depth_range``, cut in ``slices``."""
        self._bind()
        _zero(self.marks)
        near, far = depth_range
        scale = self.slices / np.log(max(far / near, 1.0 + 1e-6))
        self.depth_uniforms = dict(depth_plane=np.asarray(depth_plane, np.float32),
                                   slice_map=np.array([scale, -np.log(near) * scale], np.float32))
        units = dict(gbuffer_position=position.bind(0), gbuffer_normal=normal.bind(NORMAL_UNIT))
        for program in self.box_programs.values():
            program.use().set(**units, divisor=self.divisor,
                              box_texels=TEXELS["box_texels"][0],
                              origin=np.asarray(origin, np.float32),
                              **self.depth_uniforms,
                              camera_position=np.asarray(camera_position, np.float32),
                              light_vector=np.asarray(light, np.float32))
            _set(program, slices=self.slices)
        for level in range(1, self.levels + 1):
            (w, h), (cw, ch) = self.sizes[level], self.sizes[level - 1]
            program = self.box_programs["samples" if level == 1 else "nodes"].use()
            _set(program, node_size=(w, h), child_size=(cw, ch),
                 node_first=self.node_first[level],
                 child_first=self.node_first[level - 1] if level > 1 else 0)
            GL.glDispatchCompute(-(-w // 8), -(-h // 8), 1 if level == 1 else self.slices)
            _barrier()
        if self.slices > 1:
            _set(self.box_programs["merge"].use(), node_size=(1, 1), node_first=self.root,
                 child_first=self.node_first[self.levels])
            GL.glDispatchCompute(1, 1, 1)
            _barrier()

    def traverse(self, position: Texture, vertices: int, light: np.ndarray,
                 axis: np.ndarray, origin: np.ndarray, tie: float, view_proj: np.ndarray,
                 count: bool = False) -> np.ndarray:
        """Mark the samples and nodes inside the casters' volumes (their corners index
        ``vertices``, the scene mesh's vertex buffer) for ``light`` (homogeneous), positions
        taken relative to ``origin`` (float32, near the scene); ``axis``, a direction the
        light's rays take (ptsv_volume.glsl's cross-section bounds); ``view_proj``, the
        camera's, which places each volume's footprint on the screen (where its traversal
        starts). The casters go in batches (all at once unless a frame needed more room): a
        batch whose queues or seeds overflowed runs again with room (marks only ever go from
        lit to shadowed, so a batch run twice marks what it marks once), or, once the queues
        are at ``MAX_CAPACITY``, as two halves. Returns the counters (read back), summed over
        the batches. The marks are those :meth:`build` left (it comes first)."""
        clip = np.array(view_proj, np.float64)  # of positions relative to origin
        clip[:, 3] += clip[:, :3] @ np.asarray(origin, np.float64)
        uniforms = dict(_across(light, axis, np.asarray(origin, np.float64)),
                        clip_from_scene=clip)
        total = np.zeros(self.counter_count, np.int64)
        self.peak = self.batches = start = 0
        while start < self.caster_count:
            end = min(start + self.batch, self.caster_count)
            counters = self._traverse_batch(position, vertices, light, uniforms, origin,
                                            tie, count, start, end)
            needed = int(counters[COUNT_LEVELS:self.seed_counts].max(initial=0))
            volumes = int(counters[0])
            seeds = int(counters[self.seed_counts:self.seed_counts + self.levels + 1].sum())
            if seeds > self.seed_capacity:  # the batch runs again with room
                self._grow_seeds(1 << max(seeds - 1, 1).bit_length())
                continue
            if needed <= self.capacity and volumes <= self.volume_capacity:
                total += counters
                self.peak = max(self.peak, needed)
                self.batches += 1
                start = end
                continue
            if self.capacity < MAX_CAPACITY or needed <= MAX_CAPACITY:
                self._grow(min(1 << max(needed - 1, 1).bit_length(), MAX_CAPACITY),
                           1 << max(volumes - 1, 1).bit_length())
            else:
                self.batch = max(1, (end - start) // 2)
        return total

    def _traverse_batch(self, position, vertices, light, uniforms, origin, tie, count,
                        start: int, end: int) -> np.ndarray:
        _zero(self.counters)
        # attached every batch: a moved scene's mesh is new buffers, maybe under the old names
        GL.glBindBuffer(GL.GL_TEXTURE_BUFFER, vertices)
        nbytes = int(GL.glGetBufferParameteriv(GL.GL_TEXTURE_BUFFER, GL.GL_BUFFER_SIZE))
        GL.glBindBuffer(GL.GL_TEXTURE_BUFFER, 0)
        _texels(self.textures["vertex_texels"], "vertex_texels", vertices, nbytes)
        self._bind()
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 7, self.dispatch)
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 8, self.closed_side)
        shared = dict(**uniforms, origin=np.asarray(origin, np.float32), tie=float(tie),
                      capacity=self.capacity, volume_capacity=self.volume_capacity, sample_count=self.samples,
                      slices=self.slices)
        setup = self.setup_programs[count].use()
        setup.set(**TEXEL_UNITS, **self.depth_uniforms,
                  sample_scale=np.array(self.sizes[0], np.float32) * 0.5)
        _set(setup, light_vector=np.asarray(light, np.float32), first_caster=start,
             caster_end=end, root=self.root, root_level=self.levels,
             top_first=self.node_first[self.levels], sample_size=self.sizes[0], **shared)
        GL.glDispatchCompute(*_rows(-(-(end - start) // 64)), 1)
        _barrier()
        _set(self.seed_offsets.use(), **shared)
        GL.glDispatchCompute(1, 1, 1)
        _barrier()
        _set(self.seed_scatter.use(), seed_capacity=self.seed_capacity, **shared)
        GL.glDispatchCompute(*_rows(-(-(end - start) // 64)), 1)
        _barrier()
        seed = self.seed_programs[count].use()
        seed.set(**TEXEL_UNITS)
        _set(seed, seed_capacity=self.seed_capacity, **shared)
        for leaf in (False, True):
            traverse = self.traverse_programs[count, leaf]
            traverse.use().set(gbuffer_position=position.bind(0), divisor=self.divisor,
                               **TEXEL_UNITS)
            _set(traverse, **shared)
        GL.glBindBuffer(GL.GL_DISPATCH_INDIRECT_BUFFER, self.dispatch)
        for level in range(self.levels, 0, -1):
            if level < self.levels:
                _set(self.dispatch_program.use(), counter=self.seed_counts + level,
                     limit=self.seed_capacity, items_per_group=64)
                GL.glDispatchCompute(1, 1, 1)
                _barrier()
                _set(self.seed_programs[count].use(), level=level, node_size=self.sizes[level],
                     node_first=self.node_first[level])
                GL.glDispatchComputeIndirect(0)
                _barrier()
            _set(self.dispatch_program.use(), counter=COUNT_LEVELS + level,
                 limit=self.capacity, items_per_group=self.items_per_group)
            GL.glDispatchCompute(1, 1, 1)
            _barrier()
            cw, ch = self.sizes[level - 1]
            _set(self.traverse_programs[count, level == 1].use(), level=level,
                 node_first=self.node_first[level], node_size=self.sizes[level],
                 child_size=(cw, ch),
                 child_first=self.node_first[level - 1] if level > 1 else 0)
            GL.glDispatchComputeIndirect(0)
            _barrier()
        GL.glBindBuffer(GL.GL_DISPATCH_INDIRECT_BUFFER, 0)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.counters)
        counters = np.frombuffer(GL.glGetBufferSubData(
            GL.GL_SHADER_STORAGE_BUFFER, 0, self.counter_count * 4),
            np.uint32).copy()
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        GL.glUseProgram(0)
        return counters

    def counts(self, counters: np.ndarray) -> dict:
        """The counted work of the last traversal (run with ``count``) as result columns:
        ``queue_peak`` is the most items one level's queue held in one batch."""
        queued = counters[COUNT_LEVELS + 1:COUNT_LEVELS + self.levels + 1]
        out = {name: int(counters[i]) for i, name in enumerate(COUNTER_NAMES)}
        out.update(queue_items=int(queued.sum()), queue_peak=self.peak,
                   traversal_batches=self.batches, hierarchy_levels=self.levels)
        return out

    def release(self) -> None:
        GL.glDeleteTextures(len(self.textures), list(self.textures.values()))
        GL.glDeleteBuffers(11, [self.boxes, self.marks, self.counters, self.dispatch,
                                self.queues, self.planes, self.starts, self.seeds,
                                self.closed_side, self.sample_slices, self.casters])
        for program in (*self.box_programs.values(), self.dispatch_program,
                        *self.setup_programs.values(), *self.seed_programs.values(),
                        self.seed_offsets, self.seed_scatter,
                        *self.traverse_programs.values()):
            program.release()
