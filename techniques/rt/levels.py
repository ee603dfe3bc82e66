"""The two-level BVH as engines build one, in buffer textures for ``rt_trace.comp.glsl``.

Bottom level: one BVH per part over its triangles in the part's own space (as ``prepare`` saw
it, frame 0), built once. Top level: one BVH over the parts' instances, the boxes of their
bottom-level roots moved by their poses (``Frame.part_poses``), rebuilt by :meth:`rebuild_top`
(one leaf per instance). Everything is read through buffer textures (``texelFetch``): the
harness measured llvmpipe's storage-buffer loads 1.9x slower (``harness.gl.geometry``), and
for this traversal, the same shader reading std430 storage buffers instead (same V, bit for
bit) took 639 and 414 ms against 319 and 149 ms for castle's trace pass at 512^2, and 1171
and 520 against 1080 and 151 ms on architecture at 10^5 triangles (two alternating rounds on
2 busy cores, contention 0.57-0.93: noisy, but storage buffers slower every time).
"""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from harness.gl.geometry import BufferTexture

from . import bvh

TRIANGLE_BYTES = 48  # three RGBA32F texels
CUTOUT_BYTES = 32  # two RGBA32F texels: the corners' texture coordinates, the cut-out's index
INSTANCE_BYTES = 64  # four RGBA32F texels


def bound_bytes(triangles: int, cutouts: bool = False) -> int:
    """Bytes the bottom levels may take for ``triangles``, whatever the builder: every
    triangle's texels (with ``cutouts``, its texture coordinates' too) and a binary tree's
    most nodes (one triangle per leaf). The budget check refuses a scene on this before
    building anything."""
    per_triangle = TRIANGLE_BYTES + (CUTOUT_BYTES if cutouts else 0)
    return triangles * per_triangle + bvh.max_records(triangles) * bvh.RECORD_BYTES


def _moved_boxes(lo: np.ndarray, hi: np.ndarray, poses: np.ndarray):
    """World boxes of boxes ``lo``/``hi`` (P, 3) moved by the rigid ``poses`` (P, 4, 4): the
    centre moved, the half extents through the rotation's absolute values (Arvo 1990: the
    bounds of the 8 moved corners), in float64, widened to the next float32 outwards (never
    smaller than exact)."""
    centre = (lo.astype(np.float64) + hi) / 2
    half = (hi.astype(np.float64) - lo) / 2
    rotation = poses[:, :3, :3]
    centre = np.matmul(rotation, centre[..., None])[..., 0] + poses[:, :3, 3]
    half = np.matmul(np.abs(rotation), half[..., None])[..., 0]
    low = np.nextafter((centre - half).astype(np.float32), np.float32(-np.inf))
    high = np.nextafter((centre + half).astype(np.float32), np.float32(np.inf))
    return low, high


def _cutout_texels(part, masks: tuple, order: np.ndarray) -> np.ndarray:
    """``rt_trace.comp.glsl``'s ``cutouts`` of ``part``'s triangles in leaf ``order``: (u0, v0,
    u1, v1), (u2, v2, the index of its cut-out in ``masks`` or -1, 0)."""
    texels = np.zeros((len(order), 2, 4), np.float32)
    texels[:, 1, 2] = -1.0
    if part.alpha is not None:
        uv = part.texcoords[order].reshape(-1, 6)
        texels[:, 0] = uv[:, :4]
        texels[:, 1, :2] = uv[:, 4:]
        texels[:, 1, 2] = next(i for i, m in enumerate(masks) if m is part.alpha)
    return texels.reshape(-1, 4)


class TwoLevelBvh:
    """Bottom levels of ``parts`` (those with triangles) by ``build`` with ``leaf_size``. With
    ``masks`` (the scene's ``alpha_masks``, where it has cut-outs) each triangle's texture
    coordinates and cut-out also go up, in leaf order (``cutouts``)."""

    def __init__(self, parts, build: str, leaf_size: int, masks: tuple = ()):
        self.used = [i for i, part in enumerate(parts) if len(part.faces)]
        # the top level's records first, in the same buffer: one fetch path for both levels
        self.top_records = bvh.max_records(len(self.used))
        top_slots = max(self.top_records, 1)
        records, triangles, roots, depths = [np.zeros((4 * top_slots, 4), np.float32)], [], [], []
        cutouts = []
        record_offset, triangle_offset = top_slots, 0
        part_corners = [parts[i].vertices[parts[i].faces] for i in self.used]
        trees = bvh.build_all([bvh.triangle_boxes(c) for c in part_corners], build, leaf_size)
        for tree, corners, used in zip(trees, part_corners, self.used):  # one tree per part
            records.append(tree.texels(record_offset, triangle_offset))
            padded = np.zeros((len(tree.order), 3, 4), np.float32)
            padded[..., :3] = corners[tree.order]
            triangles.append(padded.reshape(-1, 4))
            if masks:
                cutouts.append(_cutout_texels(parts[used], masks, tree.order))
            roots.append((tree.entries(record_offset, triangle_offset)[0], tree.lo[0],
                          tree.hi[0]))
            depths.append(tree.depth)
            record_offset += tree.record_count
            triangle_offset += len(tree.order)
        self.empty = not self.used
        self.record_count, self.triangle_count = record_offset - top_slots, triangle_offset
        self.root_entries = np.array([r[0] for r in roots], np.uint32)
        self.root_lo = np.array([r[1] for r in roots], np.float32).reshape(-1, 3)
        self.root_hi = np.array([r[2] for r in roots], np.float32).reshape(-1, 3)
        self.bottom_depth = max(depths, default=0)
        self.top_root = 0  # the top level's root entry: a record, or one instance's leaf
        self.top_depth = bvh.lbvh_depth_bound(len(self.used))  # whatever the poses
        empty = np.zeros((1, 4), np.float32)
        self.nodes = BufferTexture(np.concatenate(records), GL.GL_RGBA32F, dynamic=True)
        self.triangles = BufferTexture(np.concatenate(triangles) if triangles else empty,
                                       GL.GL_RGBA32F)
        self.instances = BufferTexture(np.zeros((4 * max(len(self.used), 1), 4), np.float32),
                                       GL.GL_RGBA32F, dynamic=True)
        self.cutouts = (BufferTexture(np.concatenate(cutouts) if cutouts else empty,
                                      GL.GL_RGBA32F) if masks else None)

    @property
    def stack_size(self) -> int:
        """Entries the traversal's stack needs: one push per level of either tree."""
        return self.top_depth + self.bottom_depth + 1

    @property
    def bottom_bytes(self) -> int:
        per_triangle = TRIANGLE_BYTES + (CUTOUT_BYTES if self.cutouts is not None else 0)
        return self.record_count * bvh.RECORD_BYTES + self.triangle_count * per_triangle

    @property
    def nbytes(self) -> int:
        return self.bottom_bytes + self.top_records * bvh.RECORD_BYTES + \
            len(self.used) * INSTANCE_BYTES

    def rebuild_top(self, poses: np.ndarray) -> None:
        """Build the top level over the instances at ``poses`` (all parts' (P, 4, 4)) and
        upload it with each instance's world-to-object transform, in the top level's leaf
        order."""
        if self.empty:
            return
        poses = np.asarray(poses, np.float64)[self.used]
        lo, hi = _moved_boxes(self.root_lo, self.root_hi, poses)
        top = bvh.build(lo, hi, "lbvh", leaf_size=1)
        self.top_root = int(top.entries()[0])
        if top.record_count:
            self.nodes.write(top.texels())
        instances = np.zeros((len(self.used), 4, 4), np.float32)
        # a rigid pose's inverse: the rotation transposed, the translation taken back
        inverse = np.transpose(poses[:, :3, :3], (0, 2, 1))
        instances[:, :3, :3] = inverse
        instances[:, :3, 3] = -np.matmul(inverse, poses[:, :3, 3, None])[..., 0]
        instances[:, 3, 0] = self.root_entries.view(np.float32)
        self.instances.write(instances[top.order].reshape(-1, 4))  # a leaf's first: its slot

    def bind(self, program, first_unit: int) -> int:
        """Bind the buffer textures to ``program``'s samplers; returns the next unit."""
        program.set(tlas_root=self.top_root, nodes=self.nodes.bind(first_unit),
                    triangles=self.triangles.bind(first_unit + 1),
                    instances=self.instances.bind(first_unit + 2))
        if self.cutouts is None:
            return first_unit + 3
        program.set(cutouts=self.cutouts.bind(first_unit + 3))
        return first_unit + 4

    def release(self) -> None:
        for texture in (self.nodes, self.triangles, self.instances, self.cutouts):
            if texture is not None:
                texture.release()
