"""A k-d tree of training inputs, built in numpy and queried by numba one row at a time.

:func:`build_kdtree` splits a point set at the median of its widest coordinate until a node
holds at most `leaf_size` points; the points are reordered so that every leaf's are
contiguous. :func:`nearest_distance` is the exact Euclidean distance from a row to the
nearest of them (branch and bound), a few hundred flops for thousands of points in 7-D:
cheap enough for a 1 kHz control loop (``benchmarks/compensator_latency.py``).

Arrays (the kernel's arguments): ``points`` (M, d) float64; ``nodes`` (K, 5) int64, per node
``[split dimension (−1: leaf), left child, right child, first point, end point]``;
``splits`` (K,) float64, a node's split value (go left when ``x[dim] <= split``).
"""

from __future__ import annotations

import numba
import numpy as np

LEAF = -1


def build_kdtree(points, leaf_size: int = 16) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points reordered (M, d), nodes (K, 5), splits (K,)) of `points` (M, d), M >= 1."""
    points = np.ascontiguousarray(points, dtype=float)
    if points.ndim != 2 or len(points) == 0:
        raise ValueError(f"build_kdtree: points must be (M, d) with M >= 1; got {points.shape}")
    order = np.arange(len(points))
    nodes, splits = [], []
    todo = [(0, len(points), -1, 0)]  # (start, end, parent, which child slot of the parent)
    while todo:
        start, end, parent, slot = todo.pop()
        node = len(nodes)
        if parent >= 0:
            nodes[parent][slot] = node
        block = points[order[start:end]]
        spread = block.max(axis=0) - block.min(axis=0)
        if end - start <= leaf_size or spread.max() == 0.0:
            nodes.append([LEAF, -1, -1, start, end])
            splits.append(0.0)
            continue
        dim = int(np.argmax(spread))
        sorted_block = np.argsort(block[:, dim], kind="stable")
        order[start:end] = order[start:end][sorted_block]
        middle = start + (end - start) // 2
        split = float(points[order[middle - 1], dim])
        nodes.append([dim, -1, -1, start, end])
        splits.append(split)
        todo.append((middle, end, node, 2))
        todo.append((start, middle, node, 1))
    return (np.ascontiguousarray(points[order]), np.array(nodes, dtype=np.int64),
            np.array(splits, dtype=float))


@numba.njit(cache=True, nogil=True)
def nearest_distance(x, points, nodes, splits) -> float:
    """Euclidean distance from x (d,) to the nearest of the tree's points (∞ without any).

    Points tied on the split value may sit on either side of it; the bound (x − split)² is
    a lower bound for the far side either way, so the result is exact."""
    if len(nodes) == 0:
        return np.inf
    d = points.shape[1]
    best = np.inf
    stack = np.empty(128, np.int64)
    bounds = np.empty(128)
    stack[0], bounds[0], top = 0, 0.0, 1
    while top > 0:
        top -= 1
        node, bound = stack[top], bounds[top]
        if bound >= best:
            continue
        dim = nodes[node, 0]
        if dim == LEAF:
            for i in range(nodes[node, 3], nodes[node, 4]):
                total = 0.0
                for j in range(d):
                    diff = x[j] - points[i, j]
                    total += diff * diff
                    if total >= best:
                        break
                best = min(best, total)
            continue
        diff = x[dim] - splits[node]
        near, far = (nodes[node, 1], nodes[node, 2]) if diff <= 0.0 else (nodes[node, 2],
                                                                           nodes[node, 1])
        far_bound = max(bound, diff * diff)
        if top + 2 > len(stack):  # deeper than any tree of < 2⁶⁰ points; kept safe anyway
            return np.sqrt(best)
        stack[top], bounds[top] = far, far_bound
        stack[top + 1], bounds[top + 1] = near, bound
        top += 2
    return np.sqrt(best)


@numba.njit(cache=True, nogil=True)
def nearest_distances(X, points, nodes, splits, out) -> None:
    """out (N,) = :func:`nearest_distance` of every row of X (N, d)."""
    for r in range(len(X)):
        out[r] = nearest_distance(X[r], points, nodes, splits)
