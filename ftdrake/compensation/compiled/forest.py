"""Regression forests flattened into arrays and walked by numba, one row at a time.

Equal to scikit-learn's ``predict`` to rounding: the same float32 cast of the input, the same
``<=`` rule, the same summation order. :func:`forest_accumulate` is the numba kernel other
compiled code (``CompensatorSystem``'s fused update) calls directly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from sklearn.base import is_regressor

from .rows import checked_row, checked_rows, joints_for, nonfinite_error

# One interior node of a flattened tree. A child index ``c >= 0`` is another interior node;
# ``c < 0`` is the leaf ``-1 - c`` (a row of `leaf_values`).
NODE_DTYPE = np.dtype(
    [("feature", np.int32), ("left", np.int32), ("right", np.int32), ("threshold", np.float32)]
)
# One tree: its root (a child index, as above) and the output columns its leaves add to.
TREE_DTYPE = np.dtype(
    [("root", np.int32), ("column", np.int32), ("width", np.int32), ("first_leaf", np.int32)]
)




def _floor_to_float32(t: np.ndarray) -> np.ndarray:
    """The largest float32 <= t, element-wise.

    scikit-learn compares ``float64(float32(x)) <= t``; for a float32 value v,
    ``v <= t`` exactly when ``v <= floor32(t)``, so storing floor32(t) lets the walk compare
    in float32, with bit-identical decisions, and keeps a node in 16 bytes.
    """
    t32 = t.astype(np.float32)
    above = t32.astype(np.float64) > t
    t32[above] = np.nextafter(t32[above], np.float32(-np.inf))
    return t32


def _as_forest_list(forests) -> list:
    forests = list(forests) if isinstance(forests, (list, tuple)) else [forests]
    if not forests:
        raise ValueError("no forests given")
    for forest in forests:
        trees = getattr(forest, "estimators_", None)
        if not trees or not all(hasattr(tree, "tree_") for tree in trees):
            raise ValueError(f"{forest!r} is not a fitted forest of decision trees")
        if not is_regressor(forest):
            raise ValueError(f"{forest!r} is not a regressor; only regression forests compile")
    n_used = {forest.n_features_in_ for forest in forests}
    if len(n_used) > 1:
        raise ValueError(f"the forests take different numbers of inputs: {sorted(n_used)}")
    return forests


@dataclass(frozen=True, eq=False)  # holds arrays: no field-wise ==
class FlatForest:
    """Regression forests as flat arrays, prediction = per-output mean of the trees' leaves.

    Forest f's outputs are the columns following those of forests 0..f-1, so a list of k
    single-output forests and one k-output forest both give k outputs.

    nodes: (n_interior,) NODE_DTYPE – feature, children, float32 threshold (go left if
        ``float32(x[feature]) <= threshold``, scikit-learn's rule).
    leaf_values: (n_leaves, w) float64 – a leaf's value per output of its forest; w is the
        largest forest output count (unused columns are 0).
    trees: (n_trees,) TREE_DTYPE – root, first output column, output count, first leaf.
    n_trees: (k,) float64 – the number of trees averaged into each output.
    n_inputs: int – input columns the trees index (the selected features).
    """

    nodes: np.ndarray
    leaf_values: np.ndarray
    trees: np.ndarray
    n_trees: np.ndarray
    n_inputs: int

    @property
    def n_outputs(self) -> int:
        return len(self.n_trees)


def flatten_forests(forests) -> FlatForest:
    """Flattens fitted scikit-learn regression forests (a list, or one forest)."""
    forests = _as_forest_list(forests)
    width = max(forest.n_outputs_ for forest in forests)
    nodes, leaf_values, trees, n_trees = [], [], [], []
    n_interior = n_leaves = column = 0
    for forest in forests:
        for estimator in forest.estimators_:
            tree = estimator.tree_
            left, right = tree.children_left, tree.children_right
            is_leaf = left < 0
            interior, leaves = np.flatnonzero(~is_leaf), np.flatnonzero(is_leaf)
            index = np.empty(tree.node_count, np.int64)  # sklearn node id -> child index
            index[interior] = n_interior + np.arange(len(interior))
            index[leaves] = -1 - (n_leaves + np.arange(len(leaves)))
            block = np.empty(len(interior), NODE_DTYPE)
            block["feature"] = tree.feature[interior]
            block["left"] = index[left[interior]]
            block["right"] = index[right[interior]]
            block["threshold"] = _floor_to_float32(tree.threshold[interior])
            nodes.append(block)
            values = np.zeros((len(leaves), width))
            values[:, : forest.n_outputs_] = tree.value[leaves, :, 0]
            leaf_values.append(values)
            trees.append((index[0], column, forest.n_outputs_, n_leaves))
            n_interior += len(interior)
            n_leaves += len(leaves)
        n_trees += [len(forest.estimators_)] * forest.n_outputs_
        column += forest.n_outputs_
    return FlatForest(
        nodes=np.concatenate(nodes),
        leaf_values=np.concatenate(leaf_values),
        trees=np.array(trees, dtype=TREE_DTYPE),
        n_trees=np.array(n_trees, dtype=np.float64),
        n_inputs=forests[0].n_features_in_,
    )


_GROUP = 8  # trees walked in lockstep, so that their memory loads overlap (~2× faster)


@njit(cache=True, nogil=True)
def forest_accumulate(x, nodes, leaf_values, trees, n_trees, out):
    """out (k,) = mean over each output's trees of the leaf that row x reaches."""
    out[:] = 0.0
    at = np.empty(_GROUP, np.int32)
    for first in range(0, len(trees), _GROUP):
        group = min(_GROUP, len(trees) - first)
        for i in range(group):
            at[i] = trees[first + i].root
        walking = True
        while walking:
            walking = False
            for i in range(group):
                if at[i] >= 0:
                    node = nodes[at[i]]
                    if np.float32(x[node.feature]) <= node.threshold:
                        at[i] = node.left
                    else:
                        at[i] = node.right
                    walking = True
        # Summed tree by tree, then divided, in scikit-learn's order.
        for i in range(group):
            tree = trees[first + i]
            for j in range(tree.width):
                out[tree.column + j] += leaf_values[-1 - at[i], j]
    for j in range(len(out)):
        out[j] /= n_trees[j]


@njit(cache=True, nogil=True)
def forest_accumulate_with_std(x, nodes, leaf_values, trees, n_trees, out, std):
    """:func:`forest_accumulate` into `out` (the same sums, bit-equal), and into `std` (k,)
    each output's spread across its trees, √(mean of squares − mean²), in the same walk (not
    a calibrated uncertainty; see :mod:`ftdrake.compensation.estimators.forest`).

    The lockstep walk is written out again here rather than shared with forest_accumulate:
    a shared inlined helper was slower.
    """
    out[:] = 0.0
    std[:] = 0.0
    at = np.empty(_GROUP, np.int32)
    for first in range(0, len(trees), _GROUP):
        group = min(_GROUP, len(trees) - first)
        for i in range(group):
            at[i] = trees[first + i].root
        walking = True
        while walking:
            walking = False
            for i in range(group):
                if at[i] >= 0:
                    node = nodes[at[i]]
                    if np.float32(x[node.feature]) <= node.threshold:
                        at[i] = node.left
                    else:
                        at[i] = node.right
                    walking = True
        for i in range(group):
            tree = trees[first + i]
            for j in range(tree.width):
                value = leaf_values[-1 - at[i], j]
                out[tree.column + j] += value
                std[tree.column + j] += value * value
    for j in range(len(out)):
        out[j] /= n_trees[j]
        std[j] = np.sqrt(max(std[j] / n_trees[j] - out[j] * out[j], 0.0))


@njit(cache=True, nogil=True)
def _forest_predict_one(x, nodes, leaf_values, trees, n_trees, out):
    """Fills out (k,) from one row x (3n,); returns False (out untouched) if x has NaN/inf."""
    for value in x:
        if not np.isfinite(value):
            return False
    forest_accumulate(x, nodes, leaf_values, trees, n_trees, out)
    return True


@njit(cache=True, nogil=True)
def _forest_predict(X, nodes, leaf_values, trees, n_trees, out):
    """Fills out (N, k) from rows X (N, 3n), already checked."""
    for r in range(len(X)):
        forest_accumulate(X[r], nodes, leaf_values, trees, n_trees, out[r])


class CompiledForest:
    """scikit-learn regression forests, compiled for single-row prediction in a control loop.

    Equal to the forests' ``predict`` (stacked column-wise for a list) to rounding, ~1e-16:
    the same float32 cast of the input, the same ``<=`` rule, the same summation order.

    Parameters
    ----------
    forests : a fitted ``RandomForestRegressor`` (or ``ExtraTreesRegressor``), or a list of
        them (one per output, or any mix); all take the same selected features.
    features : {"q", "q,qd", "q,qd,qdd"}
        The feature set the forests were trained on.
    n_joints : int, optional
        Checked against the forests' input count if given.

    The numba functions are compiled (or loaded from numba's cache) and run once here, so
    the first ``predict_one`` in a control loop is as fast as the rest.
    """

    def __init__(self, forests, features: str = "q,qd,qdd", n_joints: int | None = None):
        self.flat = flatten_forests(forests)
        self.features = features
        self.n_joints = joints_for(self.flat.n_inputs, features, n_joints)
        self.n_outputs = self.flat.n_outputs
        # (nodes, leaf_values, trees, n_trees): the arguments of forest_accumulate.
        self.arrays = (self.flat.nodes, self.flat.leaf_values, self.flat.trees, self.flat.n_trees)
        self.predict(np.zeros((2, 3 * self.n_joints)))
        self.predict_one(np.zeros(3 * self.n_joints))
        self.predict_one_with_std(np.zeros(3 * self.n_joints))

    def onnx_parts(self) -> FlatForest:
        """The flattened forests: the form :mod:`ftdrake.compensation.files.onnx_export` writes."""
        return self.flat

    def predict(self, X) -> np.ndarray:
        """X: (N, 3n) rows of [q, q̇, q̈]. Returns (N, k)."""
        X = checked_rows(X, self.n_joints)
        out = np.empty((len(X), self.n_outputs))
        _forest_predict(X, *self.arrays, out)
        return out

    def predict_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x: (3n,) one row of [q, q̇, q̈]. Returns (k,), written into `out` if given.

        `out` must be a C-contiguous float64 (k,) array.
        """
        x = checked_row(x, self.n_joints)
        if out is None:
            out = np.empty(self.n_outputs)
        if not _forest_predict_one(x, *self.arrays, out):
            raise nonfinite_error(x)
        return out

    def predict_one_with_std(self, x) -> tuple[np.ndarray, np.ndarray]:
        """x: (3n,) → (mean (k,), spread across trees (k,)); the std is not calibrated."""
        x = checked_row(x, self.n_joints)
        if not np.isfinite(x).all():
            raise nonfinite_error(x)
        out, std = np.empty(self.n_outputs), np.empty(self.n_outputs)
        forest_accumulate_with_std(x, *self.arrays, out, std)
        return out, std
