"""Bounding-volume hierarchies over boxes, built top-down one level at a time with NumPy.

Every node of a level is split at once: its primitives lie in one contiguous range of
``order``, so a level is a handful of array operations over all its primitives (no Python loop
per triangle or per node; a loop per level, about log2 of the count). Two split rules:

- ``lbvh``, Karras (HPG 2012): primitives sorted once by the 30-bit Morton code of their
  centroid (10 bits per axis in the bounds of all centroids); a node splits where its codes'
  highest differing bit turns from 0 to 1 (Karras's ``findSplit``: one ``searchsorted`` per
  level over the sorted codes), in the middle of a run of equal codes.
- ``sah``, binned surface-area heuristic (Wald 2007): 16 bins along the longest axis of the
  node's centroid bounds; the split between bins that minimises n_left x area_left +
  n_right x area_right; primitives partitioned stably; a node whose centroids all fall in
  one bin splits at the middle of its range. The bins' boxes come from one ``ufunc.at`` per
  box coordinate (no sort), the children's boxes from the bins, a level's nodes are binned
  8192 at a time (their bins stay in cache), and only inner nodes' primitives take part in a
  level. ``build_all`` builds a scene's parts as one forest, a level of every part at once.
  At 10^6 triangles (``benchmarks/rt_speed.py build``, triangles' boxes included, 2 shared
  cores at load average 2.4-2.7): 1.0-1.5 s on tessellation (2 parts) and 1.3-1.8 s on
  architecture (168 parts), against 4.7-5.6 s and 4.6-4.9 s before (a build per part, with a
  stable argsort and 2-D gathers per level); the same trees bit for bit.

A node holding ``leaf_size`` primitives or fewer is a leaf. Children of a node are adjacent
(``first``, ``first + 1``), so a node stores one index. The result is a :class:`Bvh`; for the
traversal it becomes :meth:`Bvh.texels`: one record per internal node holding both children's
boxes (Aila and Laine 2009), so a step of the traversal tests two boxes and enters only the
children it hits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BUILDERS = ("lbvh", "sah")
SAH_BINS = 16
RECORD_BYTES = 64  # four RGBA32F texels: (lo, entry), (hi, -) of each child
# An entry names a child: an internal node, its record's index (count bits 0); a leaf, its
# primitive count (1..16) in the top 5 bits over its first primitive
COUNT_SHIFT = 27
MAX_LEAF = 16
SAH_CHUNK = 8192  # nodes binned together: their bins' arrays (6 x 16 x 4 B each) stay in cache


@dataclass
class Bvh:
    lo: np.ndarray  # (N, 3) float32 node boxes
    hi: np.ndarray
    first: np.ndarray  # (N,) int64: first child (internal) or first entry of ``order`` (leaf)
    count: np.ndarray  # (N,) int64: 0 for an internal node, primitives for a leaf
    order: np.ndarray  # (T,) int64: primitive indices in leaf order
    depth: int = 0  # edges from the root to the deepest leaf

    @property
    def nodes(self) -> int:
        return len(self.first)

    @property
    def record_count(self) -> int:
        """Internal nodes: the records :meth:`texels` writes."""
        return int((self.count == 0).sum())

    def entries(self, record_offset: int = 0, primitive_offset: int = 0) -> np.ndarray:
        """Each node's entry (uint32), record indices and primitives shifted by the offsets
        (where this BVH sits in a buffer shared with others)."""
        internal = self.count == 0
        record = np.cumsum(internal) - 1 + record_offset
        if ((self.first + primitive_offset)[~internal] >= 1 << COUNT_SHIFT).any() or \
                self.count.max(initial=0) > MAX_LEAF:
            raise ValueError(f"a leaf past primitive {1 << COUNT_SHIFT} or of more than "
                             f"{MAX_LEAF} primitives cannot be named by an entry")
        leaf = (self.count << COUNT_SHIFT) | (self.first + primitive_offset)
        return np.where(internal, record, leaf).astype(np.uint32)

    def texels(self, record_offset: int = 0, primitive_offset: int = 0) -> np.ndarray:
        """The internal nodes' records as (4 R, 4) float32 texels: each child's (lo, entry) and
        (hi, 0), the entries stored as their bits (:meth:`entries`). The root's entry is
        ``entries(...)[0]``: a BVH whose root is a leaf has no record."""
        entry = self.entries(record_offset, primitive_offset).view(np.float32)
        children = self.first[self.count == 0][:, None] + np.arange(2)
        out = np.zeros((len(children), 2, 2, 4), np.float32)
        out[:, :, 0, :3], out[:, :, 1, :3] = self.lo[children], self.hi[children]
        out[:, :, 0, 3] = entry[children]
        return out.reshape(-1, 4)


def lbvh_depth_bound(primitives: int) -> int:
    """The deepest an ``lbvh`` tree gets: one level per bit of the 30-bit codes, then halving
    runs of equal codes."""
    return 30 + max(int(primitives) - 1, 0).bit_length()


def max_records(primitives: int) -> int:
    """At most this many internal nodes (records) for ``primitives``: one per leaf but one."""
    return max(primitives - 1, 0)


def max_nodes(primitives: int) -> int:
    """At most this many nodes for ``primitives`` (a binary tree with one or more per leaf)."""
    return max(2 * primitives - 1, 1)


def _expand_bits(v: np.ndarray) -> np.ndarray:
    """10-bit integers with two zero bits after each bit (Morton interleaving)."""
    v = v.astype(np.uint32)
    v = (v * np.uint32(0x00010001)) & np.uint32(0xFF0000FF)
    v = (v * np.uint32(0x00000101)) & np.uint32(0x0F00F00F)
    v = (v * np.uint32(0x00000011)) & np.uint32(0xC30C30C3)
    v = (v * np.uint32(0x00000005)) & np.uint32(0x49249249)
    return v


def morton_codes(centroids: np.ndarray) -> np.ndarray:
    """30-bit Morton codes of points quantised to 1024 cells per axis of their bounds."""
    lo, hi = centroids.min(0), centroids.max(0)
    scale = np.where(hi > lo, 1023.999 / np.maximum(hi - lo, 1e-300), 0.0)
    q = np.clip(((centroids - lo) * scale).astype(np.int64), 0, 1023)
    return ((_expand_bits(q[:, 0]) << np.uint32(2)) | (_expand_bits(q[:, 1]) << np.uint32(1))
            | _expand_bits(q[:, 2])).astype(np.int64)


def _lbvh_split(codes: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    first, last = codes[start], codes[end - 1]
    differ = first ^ last
    bit = np.frexp(np.maximum(differ, 1).astype(np.float64))[1] - 1  # highest differing bit
    threshold = last & ~((np.int64(1) << bit) - 1)  # the common prefix, then that bit set
    split = np.searchsorted(codes, threshold, side="left")
    return np.where(differ == 0, (start + end) // 2, split)


def _area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Half the surface area of boxes given as (3, ...) corners (0 for an empty box)."""
    d = np.subtract(hi, lo)
    np.maximum(d, 0, out=d)
    area, term = d[0] * d[1], d[1] * d[2]
    area += term
    area += np.multiply(d[2], d[0], out=term)
    return area


def _accumulate(ufunc, a: np.ndarray) -> np.ndarray:
    """``ufunc.accumulate(a, axis=1)`` over (K, bins, M) arrays: one call while M is small, a
    loop over the bins once it is not (NumPy's accumulate along a middle axis costs 20x more
    per element than whole-slice operations at M = 60,000; the loop's 15 calls cost more
    below M = 128)."""
    if a.shape[2] < 128:
        return ufunc.accumulate(a, axis=1)
    out = np.empty_like(a)
    out[:, 0] = a[:, 0]
    for b in range(1, a.shape[1]):
        ufunc(out[:, b - 1], a[:, b], out=out[:, b])
    return out


def _sah_level(box, cen, size):
    """Binned SAH over one level's nodes, whose primitives fill ``box`` (6, P) float32
    corners and ``cen`` (3, P) float64 centroids node after node (``size`` each). Returns
    each node's left count, its children's boxes (12, M): left then right (NaN where the node
    has no SAH split: all its centroids in one bin), and each primitive's side (True: left)."""
    m, p = len(size), box.shape[1]
    seg = np.cumsum(size) - size
    cmin, cmax = np.minimum.reduceat(cen, seg, axis=1), np.maximum.reduceat(cen, seg, axis=1)
    axis = np.argmax(cmax - cmin, axis=0)
    rows = np.arange(m)
    extent, base = (cmax - cmin)[axis, rows], cmin[axis, rows]
    scale = np.where(extent > 0, SAH_BINS / np.where(extent > 0, extent, 1), 0)
    # per-node values repeated over the node's primitives (cheaper than gathers by node)
    ca = np.take(cen.ravel(), np.repeat(axis * p, size) + np.arange(p))
    ca -= np.repeat(base, size)
    ca *= np.repeat(scale, size)
    bins = np.minimum(ca.astype(np.int64), SAH_BINS - 1)  # ca >= 0: its node's minimum
    # each bin's count and box, bin-major: (6, bin, node); no sort, one ufunc.at per corner
    key = bins * m + np.repeat(rows, size)
    bin_count = np.bincount(key, minlength=SAH_BINS * m).reshape(SAH_BINS, m)
    bin_box = np.empty((6, SAH_BINS * m), np.float32)
    bin_box[:3], bin_box[3:] = np.inf, -np.inf
    for k in range(6):
        (np.minimum if k < 3 else np.maximum).at(bin_box[k], key, box[k])
    bin_box = bin_box.reshape(6, SAH_BINS, m)
    # boxes of bins 0..b (left) and b..15 (right), and the primitives in bins 0..b
    left = np.concatenate([_accumulate(np.minimum, bin_box[:3]), _accumulate(np.maximum, bin_box[3:])])
    right = np.concatenate([_accumulate(np.minimum, bin_box[:3, ::-1]),
                            _accumulate(np.maximum, bin_box[3:, ::-1])])[:, ::-1]
    left_n = _accumulate(np.add, bin_count[None, :-1])[0]
    right_n = size - left_n
    cost = left_n * _area(left[:3, :-1], left[3:, :-1])
    cost += right_n * _area(right[:3, 1:], right[3:, 1:])
    cost = np.where((left_n > 0) & (right_n > 0), cost, np.inf)
    best = np.argmin(cost, axis=0)
    splittable = np.isfinite(cost[best, rows])
    n_left = np.where(splittable, left_n[best, rows], size // 2)
    children = np.concatenate([left[:, best, rows], right[:, best + 1, rows]])
    children[:, ~splittable] = np.nan
    side = bins <= np.repeat(best, size)
    if not splittable.all():  # all centroids in one bin: the first half of the range
        local = np.arange(p) - np.repeat(seg, size)
        side = np.where(np.repeat(splittable, size), side, local < np.repeat(n_left, size))
    return n_left, children, side


def _build_sah(parts: list, leaf_size: int) -> list[Bvh]:
    """Top-down binned SAH over a forest, one level of every tree at a time (a scene's parts:
    a level of many small trees costs what a level of one large tree does). Only the
    primitives of inner nodes take part in a level: they sit in working arrays, node after
    node; a child that is a leaf writes its primitives to ``order`` and leaves them. Nodes
    are numbered in the order they are made, then renumbered tree by tree."""
    sizes = np.array([len(lo) for lo, _ in parts], np.int64)
    trees, n = len(parts), int(sizes.sum())
    base = np.cumsum(sizes) - sizes  # each tree's first primitive
    capacity = sum(max_nodes(int(k)) for k in sizes)
    node_lo = np.zeros((capacity, 3), np.float32)
    node_hi = np.zeros((capacity, 3), np.float32)
    first = np.zeros(capacity, np.int64)
    count = np.zeros(capacity, np.int64)
    tree = np.zeros(capacity, np.int64)  # each node's tree
    level = np.zeros(capacity, np.int64)  # edges from its root
    box = np.empty((6, n), np.float32)  # a fresh float32 (NumPy 2.4's ufunc.at is 20x slower
    for k, (lo, hi) in enumerate(parts):  # on an equal dtype that is not the builtin one)
        box[:3, base[k]:base[k] + sizes[k]], box[3:, base[k]:base[k] + sizes[k]] = lo.T, hi.T
    tree[:trees] = np.arange(trees)
    filled = sizes > 0
    if filled.any():
        for row in range(6):
            ufunc = np.minimum if row < 3 else np.maximum
            (node_lo if row < 3 else node_hi)[:trees][filled, row % 3] = \
                ufunc.reduceat(box[row], base[filled])
    root_leaf = sizes <= leaf_size
    first[:trees], count[:trees] = base, np.where(root_leaf, sizes, 0)
    order = np.arange(n)
    work = np.arange(n)  # the primitive in each working slot
    if root_leaf.any():
        active = np.repeat(~root_leaf, sizes)
        box, work = box[:, active], order[active]
    cen = (box[:3].astype(np.float64) + box[3:]) * 0.5
    ids = np.flatnonzero(~root_leaf)
    size, offset = sizes[ids], base[ids]  # offset: into ``order``
    used = trees
    while len(ids):
        m = len(ids)
        seg = np.cumsum(size) - size
        bounds = np.append(seg, len(work))
        level_parts = [_sah_level(box[:, bounds[j]:bounds[j + k]], cen[:, bounds[j]:bounds[j + k]],
                                  size[j:j + k])
                       for j in range(0, m, SAH_CHUNK) for k in [min(SAH_CHUNK, m - j)]]
        n_left, boxes, side = (np.concatenate(r, axis=-1) for r in zip(*level_parts))
        child = used + np.arange(2 * m)  # children of node j: child[2j], child[2j + 1]
        first[ids] = child[::2]
        tree[child], level[child] = np.repeat(tree[ids], 2), np.repeat(level[ids] + 1, 2)
        used += 2 * m
        child_size = np.stack([n_left, size - n_left], 1).ravel()
        child_offset = np.stack([offset, offset + n_left], 1).ravel()
        boxes = boxes.reshape(2, 6, m).transpose(2, 0, 1).reshape(2 * m, 6)
        which = np.repeat(2 * np.arange(m), size) + ~side  # each primitive's child, 0 .. 2m
        unset = np.isnan(boxes[:, 0])
        if unset.any():  # the halves of nodes without an SAH split: boxes over their ranges
            sub = box[:, unset[which]]  # those children's primitives, child after child
            sub_seg = np.cumsum(child_size[unset]) - child_size[unset]
            boxes[unset, :3] = np.minimum.reduceat(sub[:3], sub_seg, axis=1).T
            boxes[unset, 3:] = np.maximum.reduceat(sub[3:], sub_seg, axis=1).T
        node_lo[child], node_hi[child] = boxes[:, :3], boxes[:, 3:]
        leaf = child_size <= leaf_size
        first[child[leaf]], count[child[leaf]] = child_offset[leaf], child_size[leaf]
        # a stable partition: slots for the inner children's primitives, child after child,
        # then the leaves'; a primitive's slot is its child's first slot plus its rank there
        inner = ~leaf
        stay = int(child_size[inner].sum())
        target = np.empty(2 * m, np.int64)
        for kept, at in ((inner, 0), (leaf, stay)):
            target[kept] = at + np.cumsum(child_size[kept]) - child_size[kept]
        lefts = np.cumsum(side)  # left primitives up to and including each one
        left_before = lefts[seg] - side[seg]  # before each node
        target[0::2] -= left_before
        target[1::2] -= seg - left_before
        rank = np.where(side, lefts - 1, np.arange(len(side)) - lefts)
        src = np.empty(len(side), np.int64)
        src[target[which] + rank] = np.arange(len(side))
        gone = child_size[leaf]
        order[np.repeat(child_offset[leaf] - np.cumsum(gone) + gone, gone) + np.arange(gone.sum())] = \
            work[src[stay:]]
        src = src[:stay]
        box, cen, work = np.take(box, src, axis=1), np.take(cen, src, axis=1), work[src]
        ids, size, offset = child[inner], child_size[inner], child_offset[inner]
    # tree by tree: nodes in the order made (children stay adjacent), indices made local
    by_tree = np.argsort(tree[:used], kind="stable")
    nodes = np.bincount(tree[:used], minlength=trees)
    starts = np.cumsum(nodes) - nodes
    local = np.empty(used, np.int64)
    local[by_tree] = np.arange(used) - np.repeat(starts, nodes)
    inner = count[:used] == 0
    inner[:trees] &= ~root_leaf
    first = np.where(inner, local[np.where(inner, first[:used], 0)], first[:used] - base[tree[:used]])
    depth = np.maximum.reduceat(level[:used][by_tree], starts)
    node_lo, node_hi = node_lo[:used][by_tree], node_hi[:used][by_tree]
    first, count = first[by_tree], count[:used][by_tree]
    return [Bvh(node_lo[a:a + k], node_hi[a:a + k], first[a:a + k], count[a:a + k],
                order[b:b + t] - b, int(d))
            for a, k, b, t, d in zip(starts, nodes, base, sizes, depth)]


def triangle_boxes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boxes (lo, hi) of triangles given by their (T, 3, 3) corners: pairwise minima and
    maxima of the three corners, the same values as ``corners.min(1)`` in a sixth of its time
    (NumPy reduces a 3-long middle axis element by element: 0.22 s at 10^6 triangles)."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    return np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)


def build_all(boxes: list, method: str = "lbvh", leaf_size: int = 4) -> list[Bvh]:
    """One BVH per ``(lo, hi)`` of ``boxes`` (a scene's parts), each as :func:`build` makes
    it; ``sah`` builds them as one forest, level by level."""
    if method == "sah":
        return _build_sah([(np.asarray(lo, np.float32), np.asarray(hi, np.float32))
                           for lo, hi in boxes], leaf_size)
    return [build(lo, hi, method, leaf_size) for lo, hi in boxes]


def build(lo: np.ndarray, hi: np.ndarray, method: str = "lbvh", leaf_size: int = 4) -> Bvh:
    """A BVH over the boxes ``lo``/``hi`` (T, 3) by ``method`` (``BUILDERS``)."""
    if method not in BUILDERS:
        raise ValueError(f"build must be one of {BUILDERS}, got {method!r}")
    lo, hi = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
    if method == "sah":
        return _build_sah([(lo, hi)], leaf_size)[0]
    n = len(lo)
    codes = morton_codes((lo.astype(np.float64) + hi) * 0.5)
    order = np.argsort(codes, kind="stable")
    codes = codes[order]
    lo, hi = lo[order], hi[order]  # in leaf order from here
    capacity = max_nodes(n)
    node_lo = np.zeros((capacity, 3), np.float32)
    node_hi = np.zeros((capacity, 3), np.float32)
    first = np.zeros(capacity, np.int64)
    count = np.zeros(capacity, np.int64)
    ids, start, end = np.array([0]), np.array([0]), np.array([n])
    used, depth = 1, 0
    while len(ids):
        size = end - start
        leaf = size <= leaf_size
        inner = ~leaf
        if inner.any():
            s, e = start[inner], end[inner]
            split = _lbvh_split(codes, s, e)
        # node boxes over their (now partitioned) contiguous ranges
        bounds = np.stack([start, end], 1).ravel()
        bounds = bounds[bounds < n] if n else bounds[:0]
        if n:
            node_lo[ids] = np.minimum.reduceat(lo, bounds)[::2][:len(ids)]
            node_hi[ids] = np.maximum.reduceat(hi, bounds)[::2][:len(ids)]
        first[ids[leaf]], count[ids[leaf]] = start[leaf], size[leaf]
        k = int(inner.sum())
        if not k:
            break
        children = used + 2 * np.arange(k)
        first[ids[inner]] = children
        used += 2 * k
        depth += 1
        ids = np.stack([children, children + 1], 1).ravel()
        start = np.stack([s, split], 1).ravel()
        end = np.stack([split, e], 1).ravel()
    return Bvh(node_lo[:used], node_hi[:used], first[:used], count[:used], order, depth)
