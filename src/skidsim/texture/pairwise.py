"""NumPy's pairwise summation of a contiguous float64 array, evaluated block by block: the same bits as ``np.sum``
of the whole array, with every block small enough to be computed and summed while it is in cache.

NumPy sums a contiguous run of more than 128 values as the sum of its two halves, split at ``n // 2`` rounded down
to a multiple of 8, recursively; a run of at most 128 values in one unrolled block. A node of that tree summed on
its own (``np.sum`` of its contiguous slice) gives the bits it has inside the whole sum, so the leaves of the tree
cut at :data:`LEAF_POINTS` can be summed as they are produced, and :func:`tree_sum` adds them as ``np.sum`` of the
whole array would (checked in tests/test_texture_fast_paths.py, and on a float64 array of each length the texture
parameters sum)."""

from __future__ import annotations

import numpy as np

#: values per leaf of the summation tree (a few float64 arrays of it stay in cache)
LEAF_POINTS = 1 << 15


def pairwise_tree(start: int, n: int, leaf: int | None = None):
    """The summation tree of ``n`` contiguous values from ``start``, cut at nodes of at most ``leaf`` values
    (default :data:`LEAF_POINTS`; never inside a run of 128): a leaf ``(start, n)`` or a pair of subtrees."""
    leaf = LEAF_POINTS if leaf is None else leaf
    if n <= max(leaf, 128):  # NumPy sums a run of at most 128 values in one block
        return (start, n)
    half = n // 2
    half -= half % 8
    return (pairwise_tree(start, half, leaf), pairwise_tree(start + half, n - half, leaf))


def leaves(tree) -> list[tuple[int, int]]:
    """The leaves ``(start, n)`` of ``tree`` in order."""
    if isinstance(tree[0], tuple):
        return leaves(tree[0]) + leaves(tree[1])
    return [tree]


def tree_sum(tree, sums: dict) -> np.float64:
    """The whole sum from the sums of the leaves (``{leaf: np.sum of its slice}``), added as NumPy adds them."""
    if isinstance(tree[0], tuple):
        return tree_sum(tree[0], sums) + tree_sum(tree[1], sums)
    return sums[tree]
