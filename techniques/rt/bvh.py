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
  n_right x area_right; primitives partitioned stably in place; a node whose centroids all
  fall in one bin splits at the middle of its range.

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


def _sah_split(order, lo, hi, centroids, start, end) -> np.ndarray:
    """Binned SAH split of each node [start, end). ``order`` and the primitives' boxes and
    centroids (in ``order``'s order) are permuted in place."""
    counts = end - start
    m = len(start)
    node = np.repeat(np.arange(m), counts)
    pos = np.repeat(start - np.concatenate(([0], np.cumsum(counts)[:-1])), counts) + \
        np.arange(counts.sum())
    c = centroids[pos]
    seg = np.concatenate(([0], np.cumsum(counts)[:-1]))
    cmin, cmax = np.minimum.reduceat(c, seg), np.maximum.reduceat(c, seg)
    axis = np.argmax(cmax - cmin, axis=1)
    rows = np.arange(m)
    extent, base = (cmax - cmin)[rows, axis], cmin[rows, axis]
    ca = c[np.arange(len(c)), axis[node]]
    scale = np.where(extent > 0, SAH_BINS / np.where(extent > 0, extent, 1), 0)
    bins = np.clip(((ca - base[node]) * scale[node]).astype(np.int64), 0, SAH_BINS - 1)
    key = node * SAH_BINS + bins
    bin_count = np.bincount(key, minlength=m * SAH_BINS).reshape(m, SAH_BINS)
    # each non-empty bin's box: primitives grouped by bin (timsort: already grouped by node)
    grouped = np.argsort(key, kind="stable")
    heads = np.flatnonzero(np.diff(key[grouped], prepend=-1))
    filled = key[grouped[heads]]
    bin_lo = np.full((m * SAH_BINS, 3), np.inf, np.float32)
    bin_hi = np.full((m * SAH_BINS, 3), -np.inf, np.float32)
    bin_lo[filled] = np.minimum.reduceat(lo[pos][grouped], heads)
    bin_hi[filled] = np.maximum.reduceat(hi[pos][grouped], heads)
    bin_lo, bin_hi = bin_lo.reshape(m, SAH_BINS, 3), bin_hi.reshape(m, SAH_BINS, 3)

    def area(a, b):
        d = np.maximum(b - a, 0)
        return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]

    left_n = np.cumsum(bin_count, axis=1)[:, :-1]
    left_area = area(np.minimum.accumulate(bin_lo, axis=1), np.maximum.accumulate(bin_hi, axis=1))
    right_area = area(np.minimum.accumulate(bin_lo[:, ::-1], axis=1)[:, ::-1],
                      np.maximum.accumulate(bin_hi[:, ::-1], axis=1)[:, ::-1])
    right_n = counts[:, None] - left_n
    cost = left_n * left_area[:, :-1] + right_n * right_area[:, 1:]
    cost = np.where((left_n > 0) & (right_n > 0), cost, np.inf)
    best = np.argmin(cost, axis=1)
    splittable = np.isfinite(cost[rows, best])
    # partition each node's range stably: its left bins first
    left = bins <= best[node]
    left_before = np.cumsum(left) - left
    right_before = np.arange(len(left)) - left_before
    seg_left, seg_right = left_before[seg], right_before[seg]
    n_left = left_n[rows, best]
    dest = np.where(left, start[node] + left_before - seg_left[node],
                    start[node] + n_left[node] + right_before - seg_right[node])
    moved = splittable[node]
    for array in (order, lo, hi, centroids):  # all kept in leaf order
        array[dest[moved]] = array[pos[moved]]
    return np.where(splittable, start + n_left, (start + end) // 2)


def build(lo: np.ndarray, hi: np.ndarray, method: str = "lbvh", leaf_size: int = 4) -> Bvh:
    """A BVH over the boxes ``lo``/``hi`` (T, 3) by ``method`` (``BUILDERS``)."""
    if method not in BUILDERS:
        raise ValueError(f"build must be one of {BUILDERS}, got {method!r}")
    lo, hi = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
    n = len(lo)
    centroids = (lo.astype(np.float64) + hi) * 0.5
    if method == "lbvh":
        codes = morton_codes(centroids)
        order = np.argsort(codes, kind="stable")
        codes = codes[order]
    else:
        order = np.arange(n)
    lo, hi, centroids = lo[order], hi[order], centroids[order]  # in leaf order from here
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
            split = (_lbvh_split(codes, s, e) if method == "lbvh"
                     else _sah_split(order, lo, hi, centroids, s, e))
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
