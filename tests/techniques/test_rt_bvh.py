"""rt's binned SAH builder (``techniques.rt.bvh``, method ``sah``) against a plain-loop
recomputation, pure NumPy (no GL): on small random sets of boxes every node's box is the
exact union of its primitives' boxes, ``order`` is a permutation, leaves hold 1 ..
``leaf_size`` primitives, and every inner node's split is the one a loop over the 16 bins
(Wald 2007: the longest axis of the node's centroid bounds, cost n_left x area_left +
n_right x area_right) picks, or the middle of its range when all its centroids share a bin."""

from __future__ import annotations

import numpy as np
import pytest

from techniques.rt import bvh


def boxes(seed: int, count: int, duplicates: int):
    """``count`` random small boxes in the unit cube; the last ``duplicates`` of them one box
    repeated (a node of those has all its centroids in one bin)."""
    rng = np.random.default_rng(seed)
    lo = rng.random((count, 3)).astype(np.float32)
    hi = lo + (rng.random((count, 3)) * 0.1).astype(np.float32)
    lo[count - duplicates:], hi[count - duplicates:] = lo[0], hi[0]
    return lo, hi


def ranges(tree: bvh.Bvh) -> list[tuple[int, int]]:
    """Each node's range of ``order``: a leaf's own, an inner node's its children's."""
    out = [None] * tree.nodes

    def visit(i):
        if tree.count[i]:
            out[i] = (int(tree.first[i]), int(tree.first[i] + tree.count[i]))
        else:
            (a, b), (c, d) = visit(tree.first[i]), visit(tree.first[i] + 1)
            assert b == c, (i, b, c)  # the left child's primitives, then the right's
            out[i] = (a, d)
        return out[i]

    visit(0)
    return out


def half_area(lo: np.ndarray, hi: np.ndarray) -> float:
    d = hi.max(0).astype(np.float64) - lo.min(0)
    return d[0] * d[1] + d[1] * d[2] + d[2] * d[0]


def brute_force_split(lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    """The left side (a mask) of the cheapest binned-SAH split of these primitives, by a loop
    over the 16 bins; None when no split leaves both sides non-empty."""
    c = (lo.astype(np.float64) + hi) * 0.5
    axis = int(np.argmax(c.max(0) - c.min(0)))
    extent = c[:, axis].max() - c[:, axis].min()
    if extent == 0:
        return None
    bins = np.minimum(((c[:, axis] - c[:, axis].min()) * (16 / extent)).astype(int), 15)
    best, best_cost = None, np.inf
    for b in range(15):
        left = bins <= b
        if left.all() or not left.any():
            continue
        cost = (left.sum() * half_area(lo[left], hi[left])
                + (~left).sum() * half_area(lo[~left], hi[~left]))
        if cost < best_cost:
            best, best_cost = left, cost
    return best


@pytest.mark.parametrize("seed,count,duplicates,leaf_size", [
    (1, 200, 0, 4), (2, 200, 0, 1), (3, 200, 40, 4), (4, 57, 9, 2)])
def test_sah_tree_matches_a_plain_loop_over_the_bins(seed, count, duplicates, leaf_size):
    """Checked node by node against the loops above. Run against ``_sah_level`` taking the
    right side's area from the wrong bin (``right[:, :-1]``: bins b..15 instead of b+1..15)
    it fails in all four cases: "node 0 (the root): not the SAH split" for the first, node 2
    for the others. Run against the left child's box taken one bin too far
    (``left[:, best + 1]``) it fails on node 1's box (the root's left child)."""
    lo, hi = boxes(seed, count, duplicates)
    tree = bvh.build(lo, hi, "sah", leaf_size)
    np.testing.assert_array_equal(np.sort(tree.order), np.arange(count))
    span = ranges(tree)
    assert span[0] == (0, count)
    leaves = tree.count > 0
    assert (tree.count[leaves] <= leaf_size).all() and tree.count[leaves].sum() == count
    for i, (a, b) in enumerate(span):
        mine = tree.order[a:b]
        np.testing.assert_array_equal(tree.lo[i], lo[mine].min(0), err_msg=f"node {i}")
        np.testing.assert_array_equal(tree.hi[i], hi[mine].max(0), err_msg=f"node {i}")
        if leaves[i]:
            continue
        assert b - a > leaf_size, (i, a, b)
        left = brute_force_split(lo[mine], hi[mine])
        split = span[tree.first[i]][1]
        if left is None:  # all centroids in one bin: the middle of the range
            assert split - a == (b - a) // 2, (i, a, b, split)
        else:
            assert set(tree.order[a:split]) == set(mine[left]), f"node {i}: not the SAH split"


@pytest.mark.parametrize("method", bvh.BUILDERS)
def test_build_all_equals_one_build_per_part(method):
    """``build_all`` (what ``prepare`` and ``benchmarks/rt_speed.py`` call: ``sah`` builds the
    parts as one forest) gives each part the tree ``build`` gives it alone, bit for bit:
    parts of 200 and 57 boxes, one of 3 (a root leaf), one of 30 equal boxes. Run against
    the forest's leaves keeping their offsets into the forest's ``order`` (no ``- base``) it
    fails on the second part (``sah``: the empty one, whose root then points at 200, not 0)."""
    parts = [boxes(5, 200, 0), boxes(6, 3, 0), boxes(7, 57, 9), boxes(8, 30, 29)]
    if method == "sah":
        parts.insert(1, (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32)))
    for leaf_size in (1, 4):
        for k, (alone, (lo, hi)) in enumerate(zip(bvh.build_all(parts, method, leaf_size), parts)):
            tree = bvh.build(lo, hi, method, leaf_size)
            for field in ("lo", "hi", "first", "count", "order"):
                np.testing.assert_array_equal(getattr(alone, field), getattr(tree, field),
                                              err_msg=f"part {k}, {field}, leaf_size {leaf_size}")
            assert alone.depth == tree.depth, (k, leaf_size)
