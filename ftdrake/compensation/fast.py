"""Fast predictors for a 1 kHz control loop: a numba-compiled forest and a numpy kernel model.

scikit-learn's ``predict`` costs milliseconds for one row (input validation, joblib, one
Python call per tree). The predictors here take the full ``[q, q̇, q̈]`` row (3n values, rad,
rad/s, rad/s²), select the model's feature columns themselves and return the k outputs (a
wrench in N and N·m, or whatever the model was trained on), equal to scikit-learn's
``predict`` to 1e-9:

* :class:`CompiledForest` – regression forests (one per output, or one multi-output forest)
  flattened into arrays and walked by numba, a few µs per row.
* :class:`FastKernelModel` – SVRs as an input affine map, kernel expansions against stored
  points, and an output affine map.
* :class:`CompiledGaussianProcess` – a ``GPRCompensator``'s mean *and* standard deviation
  for one row by numba (kernel row, then forward substitution with the stored Cholesky
  factor), equal to its ``predict`` and ``predict_std``.

All have ``predict(X)`` for (N, 3n) → (N, k) and ``predict_one(x, out=None)`` for
(3n,) → (k,); all raise ``ValueError`` on a wrong column count or a NaN/inf input. They
always return 2-D / 1-D k-vectors, also for a model fitted on a 1-D target (k = 1).
:func:`fast_predictor` builds the right one from a fitted compensator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from sklearn.base import is_regressor

from .features import check_feature_set

# One interior node of a flattened tree. A child index ``c >= 0`` is another interior node;
# ``c < 0`` is the leaf ``-1 - c`` (a row of `leaf_values`).
NODE_DTYPE = np.dtype(
    [("feature", np.int32), ("left", np.int32), ("right", np.int32), ("threshold", np.float32)]
)
# One tree: its root (a child index, as above) and the output columns its leaves add to.
TREE_DTYPE = np.dtype(
    [("root", np.int32), ("column", np.int32), ("width", np.int32), ("first_leaf", np.int32)]
)
CHUNK_ENTRIES = 2**22  # kernel-model rows × points × features evaluated at once (32 MB)


# -- input checks ---------------------------------------------------------------------------
def _layout_error(shape, n_joints: int) -> ValueError:
    return ValueError(
        f"expected the [q, qd, qdd] layout with {3 * n_joints} columns for {n_joints} joints; "
        f"got an input of shape {shape}"
    )


def _checked_rows(X, n_joints: int) -> np.ndarray:
    """`X` as a C-contiguous float64 (N, 3n) array; ValueError on a bad shape or NaN/inf."""
    X = np.ascontiguousarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3 * n_joints:
        raise _layout_error(X.shape, n_joints)
    bad = ~np.isfinite(X).all(axis=1)
    if bad.any():
        rows = np.flatnonzero(bad)
        raise ValueError(
            f"X contains NaN or infinity in {rows.size} of {len(X)} rows "
            f"(first at row {rows[0]}); no prediction is made from such a state"
        )
    return X


def _checked_row(x, n_joints: int) -> np.ndarray:
    """`x` as a C-contiguous float64 (3n,) array; ValueError on a bad shape (not NaN)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.shape != (3 * n_joints,):
        raise _layout_error(x.shape, n_joints)
    return x


def _nonfinite_error(x: np.ndarray) -> ValueError:
    column = int(np.flatnonzero(~np.isfinite(x))[0])
    return ValueError(f"x contains NaN or infinity (first at column {column}): {x}")


def _joints_for(n_used: int, features: str, n_joints: int | None) -> int:
    """Joint count n from the model's `n_used` input columns; checks a given `n_joints`."""
    blocks = check_feature_set(features)
    if n_used % blocks or (n_joints is not None and n_used != blocks * n_joints):
        expected = "3n" if n_joints is None else blocks * n_joints
        raise ValueError(
            f"the model takes {n_used} inputs, which does not fit features={features!r} "
            f"({blocks} blocks of n joints; expected {expected})"
        )
    return n_used // blocks


# -- forests ----------------------------------------------------------------------------------
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
def _forest_accumulate(x, nodes, leaf_values, trees, n_trees, out):
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
def _forest_predict_one(x, nodes, leaf_values, trees, n_trees, out):
    """Fills out (k,) from one row x (3n,); returns False (out untouched) if x has NaN/inf."""
    for value in x:
        if not np.isfinite(value):
            return False
    _forest_accumulate(x, nodes, leaf_values, trees, n_trees, out)
    return True


@njit(cache=True, nogil=True)
def _forest_predict(X, nodes, leaf_values, trees, n_trees, out):
    """Fills out (N, k) from rows X (N, 3n), already checked."""
    for r in range(len(X)):
        _forest_accumulate(X[r], nodes, leaf_values, trees, n_trees, out[r])


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
        self.n_joints = _joints_for(self.flat.n_inputs, features, n_joints)
        self.n_outputs = self.flat.n_outputs
        self._arrays = (self.flat.nodes, self.flat.leaf_values, self.flat.trees, self.flat.n_trees)
        self.predict(np.zeros((2, 3 * self.n_joints)))
        self.predict_one(np.zeros(3 * self.n_joints))

    def predict(self, X) -> np.ndarray:
        """X: (N, 3n) rows of [q, q̇, q̈]. Returns (N, k)."""
        X = _checked_rows(X, self.n_joints)
        out = np.empty((len(X), self.n_outputs))
        _forest_predict(X, *self._arrays, out)
        return out

    def predict_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x: (3n,) one row of [q, q̇, q̈]. Returns (k,), written into `out` if given.

        `out` must be a C-contiguous float64 (k,) array.
        """
        x = _checked_row(x, self.n_joints)
        if out is None:
            out = np.empty(self.n_outputs)
        if not _forest_predict_one(x, *self._arrays, out):
            raise _nonfinite_error(x)
        return out


# -- kernel models ----------------------------------------------------------------------------
KERNELS = ("linear", "poly", "rbf", "sigmoid")


@dataclass(frozen=True, eq=False)  # holds arrays: no field-wise ==
class KernelExpansion:
    """``K(Z, points) @ weights``: one kernel evaluated against stored points.

    The shared core of kernel models: an SVR's support vectors and dual coefficients, or a
    GP's training points and ``alpha`` (its mean; its std needs `matrix` too, then a
    triangular solve with the stored Cholesky factor).

    kernel: one of KERNELS, as libsvm defines them for rows z, p:
        linear ``z·p``; poly ``(gamma z·p + coef0)^degree``; rbf ``exp(-gamma |z-p|²)``;
        sigmoid ``tanh(gamma z·p + coef0)``.
    points: (m, d) in the model's (scaled) input space.
    weights: (m, k); a column is zero for points that do not belong to that output.
    """

    kernel: str
    points: np.ndarray
    weights: np.ndarray
    gamma: float = 1.0
    coef0: float = 0.0
    degree: int = 3

    def __post_init__(self):
        if self.kernel not in KERNELS:
            raise ValueError(f"unsupported kernel {self.kernel!r}; expected one of {KERNELS}")

    def matrix(self, Z: np.ndarray) -> np.ndarray:
        """Z: (N, d). Returns the kernel matrix (N, m)."""
        if self.kernel == "rbf":
            # Differences, not |z|² + |p|² - 2 z·p: no cancellation for nearby points.
            diff = Z[:, None, :] - self.points[None, :, :]
            return np.exp(-self.gamma * np.einsum("nmd,nmd->nm", diff, diff))
        dot = Z @ self.points.T
        if self.kernel == "linear":
            return dot
        if self.kernel == "poly":
            return _powi(self.gamma * dot + self.coef0, self.degree)
        return np.tanh(self.gamma * dot + self.coef0)

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        """Z: (N, d). Returns (N, k)."""
        return self.matrix(Z) @ self.weights


@dataclass(frozen=True, eq=False)  # holds arrays: no field-wise ==
class FastKernelModel:
    """``y = target_mean + target_scale * (Σ_e e(z) + intercept)``, ``z = x_sel * scale + offset``.

    x_sel are the `features` columns of the [q, q̇, q̈] row; z is clipped to `clip` if given
    (MinMaxScaler's ``clip=True``). Build an SVR's with :meth:`from_svrs`.

    input_scale, input_offset: (d,); clip: (low, high) or None;
    expansions: tuple of KernelExpansion, each (N, d) → (N, k);
    intercept, target_mean, target_scale: (k,).
    """

    features: str
    n_joints: int
    input_scale: np.ndarray
    input_offset: np.ndarray
    clip: tuple[float, float] | None
    expansions: tuple[KernelExpansion, ...]
    intercept: np.ndarray
    target_mean: np.ndarray
    target_scale: np.ndarray

    @property
    def n_outputs(self) -> int:
        return len(self.intercept)

    @classmethod
    def from_svrs(
        cls, scaler, svrs, features: str = "q,qd,qdd", target_mean=None, target_scale=None,
        n_joints: int | None = None,
    ) -> FastKernelModel:
        """From a fitted ``MinMaxScaler`` and one fitted ``sklearn.svm.SVR`` per output.

        Outputs whose SVRs share kernel parameters share one expansion (their support
        vectors stacked). `target_mean`, `target_scale` (k,) undo a target standardisation
        (``SVRCompensator``'s ``target_mean_``, ``target_scale_``); default 0 and 1.
        """
        svrs = list(svrs)
        groups: dict[tuple, list[int]] = {}
        for j, svr in enumerate(svrs):
            if not hasattr(svr, "support_vectors_"):
                raise ValueError(f"output {j}: {svr!r} is not a fitted SVR")
            if svr.kernel not in KERNELS:
                raise ValueError(f"output {j}: unsupported kernel {svr.kernel!r}")
            key = (svr.kernel, float(svr._gamma), float(svr.coef0), int(svr.degree))
            groups.setdefault(key, []).append(j)
        k = len(svrs)
        expansions = []
        for (kernel, gamma, coef0, degree), outputs in groups.items():
            points = np.vstack([_dense(svrs[j].support_vectors_) for j in outputs])
            weights = np.zeros((len(points), k))
            start = 0
            for j in outputs:
                m = len(svrs[j].support_vectors_)
                weights[start : start + m, j] = _dense(svrs[j].dual_coef_)[0]
                start += m
            expansions.append(KernelExpansion(kernel, points, weights, gamma, coef0, degree))
        n_used = len(scaler.scale_)
        if any(svr.n_features_in_ != n_used for svr in svrs):
            raise ValueError(f"the SVRs and the scaler ({n_used} inputs) disagree on inputs")
        return cls(
            features=features,
            n_joints=_joints_for(n_used, features, n_joints),
            input_scale=np.asarray(scaler.scale_, dtype=np.float64),
            input_offset=np.asarray(scaler.min_, dtype=np.float64),
            clip=tuple(map(float, scaler.feature_range)) if scaler.clip else None,
            expansions=tuple(expansions),
            intercept=np.array([svr.intercept_[0] for svr in svrs], dtype=np.float64),
            target_mean=np.zeros(k) if target_mean is None else np.asarray(target_mean, float),
            target_scale=np.ones(k) if target_scale is None else np.asarray(target_scale, float),
        )

    def predict(self, X) -> np.ndarray:
        """X: (N, 3n) rows of [q, q̇, q̈]. Returns (N, k)."""
        X = _checked_rows(X, self.n_joints)
        m = sum(len(e.points) for e in self.expansions)
        step = max(1, CHUNK_ENTRIES // max(1, m * len(self.input_scale)))
        out = np.empty((len(X), self.n_outputs))
        for start in range(0, len(X), step):
            out[start : start + step] = self._predict(X[start : start + step])
        return out

    def predict_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x: (3n,) one row of [q, q̇, q̈]. Returns (k,), written into `out` if given."""
        x = _checked_row(x, self.n_joints)
        if not np.isfinite(x).all():
            raise _nonfinite_error(x)
        y = self._predict(x[None, :])[0]
        if out is None:
            return y
        out[:] = y
        return out

    def _predict(self, X: np.ndarray) -> np.ndarray:
        Z = X[:, : len(self.input_scale)] * self.input_scale  # the selected features
        Z += self.input_offset
        if self.clip is not None:
            np.clip(Z, *self.clip, out=Z)
        s = self.intercept + sum(expansion(Z) for expansion in self.expansions)
        return self.target_mean + self.target_scale * s


class CompiledGaussianProcess:
    """A fitted ``GPRCompensator``'s mean and std for one row at a time, compiled by numba.

    Per kernel g, with the row standardised as the model does it (z), its training rows X
    (m, d), ARD length scales l, signal variance s, noise variance n and Cholesky factor L of
    ``K + n I``: ``r = s exp(-½ |(z - X) / l|²)``, mean ``r · alpha``, ``v = L⁻¹ r`` by
    forward substitution, std ``sqrt(max(s - |v|², 0) [+ n])``; then the model's target
    scale and offset. This is the model's own formula (see ``GPRCompensator``), evaluated
    without its input validation and chunking, one kernel row at a time: O(g·m²) per row.

    The substitution runs along contiguous rows of L (vectorised). The numba function is
    compiled (or loaded from numba's cache) and run once here, so the first call in a
    control loop is as fast as the rest. The std costs O(g·m²) per row whatever the code:
    measured by ``benchmarks/compensator_latency.py``.
    """

    def __init__(self, model):
        for name in ("X_train_", "L_", "alpha_", "length_scale_", "signal_variance_",
                     "noise_variance_", "input_mean_", "input_scale_"):
            if not hasattr(model, name):
                raise ValueError(f"{type(model).__name__} is not a fitted GPRCompensator "
                                 f"(no {name})")
        self.features = model.features
        self.n_joints = int(model.n_joints_)
        self.n_outputs = int(model.n_outputs_)
        groups = model._output_groups()
        kernel_of_output = np.empty(self.n_outputs, dtype=np.int64)
        for g, cols in enumerate(groups):
            kernel_of_output[cols] = g
        f8 = np.float64
        self._arrays = (
            np.ascontiguousarray(model.input_mean_, dtype=f8),
            np.ascontiguousarray(model.input_scale_, dtype=f8),
            np.ascontiguousarray(np.asarray(model.X_train_, dtype=f8).T),
            np.ascontiguousarray(1.0 / np.asarray(model.length_scale_, dtype=f8)),
            np.ascontiguousarray(model.signal_variance_, dtype=f8),
            np.ascontiguousarray(
                model.noise_variance_ if model.include_noise else
                np.zeros_like(model.noise_variance_), dtype=f8),
            np.ascontiguousarray(model.L_, dtype=f8),
            np.ascontiguousarray(np.asarray(model.alpha_, dtype=f8).T),
            kernel_of_output,
            np.ascontiguousarray(model.target_mean_, dtype=f8),
            np.ascontiguousarray(model.target_scale_, dtype=f8),
        )
        self.predict_one_with_std(np.zeros(3 * self.n_joints))

    def predict(self, X) -> np.ndarray:
        """X: (N, 3n) rows of [q, q̇, q̈]. Returns the mean (N, k)."""
        return self.predict_with_std(X)[0]

    def predict_with_std(self, X) -> tuple[np.ndarray, np.ndarray]:
        """X: (N, 3n). Returns (mean, std), each (N, k)."""
        X = _checked_rows(X, self.n_joints)
        mean, std = np.empty((len(X), self.n_outputs)), np.empty((len(X), self.n_outputs))
        for i, x in enumerate(X):
            _gp_predict_one(x, *self._arrays, mean[i], std[i])
        return mean, std

    def predict_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x: (3n,) one row of [q, q̇, q̈]. Returns the mean (k,), written into `out` if given."""
        mean, _ = self.predict_one_with_std(x, out)
        return mean

    def predict_one_with_std(self, x, mean: np.ndarray | None = None,
                             std: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """x: (3n,). Returns (mean (k,), std (k,)), written into `mean`, `std` if given."""
        x = _checked_row(x, self.n_joints)
        if not np.isfinite(x).all():
            raise _nonfinite_error(x)
        mean = np.empty(self.n_outputs) if mean is None else mean
        std = np.empty(self.n_outputs) if std is None else std
        _gp_predict_one(x, *self._arrays, mean, std)
        return mean, std


# Reassociation lets LLVM vectorise the dot products (the substitution's inner loop is one):
# results move by rounding only (~1e-16 relative), which the equality tests bound.
@njit(cache=True, fastmath={"reassoc", "contract"})
def _gp_predict_one(x, input_mean, input_scale, points_T, inv_length, signal, noise, L,
                    alpha_T, kernel_of_output, target_mean, target_scale, mean, std):
    d, m = points_T.shape
    z = (x[:d] - input_mean) / input_scale
    r = np.empty(m)
    v = np.empty(m)
    for g in range(L.shape[0]):
        # r: the signal covariance of z with every training row; the loop over points is
        # innermost (contiguous in points_T), so it vectorises.
        r[:] = 0.0
        for c in range(d):
            zc, inv = z[c], inv_length[g, c]
            for i in range(m):
                t = (zc - points_T[c, i]) * inv
                r[i] += t * t
        for i in range(m):
            r[i] = signal[g] * np.exp(-0.5 * r[i])
        # v = L⁻¹ r by forward substitution, a row of L (contiguous) at a time.
        Lg = L[g]
        for i in range(m):
            row = Lg[i]
            acc = 0.0
            for j in range(i):
                acc += row[j] * v[j]
            v[i] = (r[i] - acc) / row[i]
        var = signal[g] - np.dot(v, v)
        sd = np.sqrt(max(var, 0.0) + noise[g])
        for o in range(len(kernel_of_output)):
            if kernel_of_output[o] == g:
                mean[o] = np.dot(r, alpha_T[o]) * target_scale[o] + target_mean[o]
                std[o] = sd * target_scale[o]


def _powi(base: np.ndarray, n: int) -> np.ndarray:
    """base**n for an int n >= 0 by repeated squaring, as libsvm computes it (and ~20× faster
    than numpy's float power)."""
    result, power = np.ones_like(base), base
    while n > 0:
        if n % 2:
            result = result * power
        n //= 2
        if n:
            power = power * power
    return result


def _dense(a) -> np.ndarray:
    return np.asarray(a.toarray() if hasattr(a, "toarray") else a, dtype=np.float64)


# -- dispatch ---------------------------------------------------------------------------------
def fast_predictor(model) -> CompiledForest | FastKernelModel | CompiledGaussianProcess:
    """The fast predictor of a fitted compensator.

    ``RandomForestCompensator`` (``forests_``) → CompiledForest; ``SVRCompensator``
    (``scaler_``, ``svrs_``, optional ``target_mean_``, ``target_scale_``) → FastKernelModel;
    ``GPRCompensator`` (``L_``, ``alpha_``) → CompiledGaussianProcess. Attribute names are
    looked up, so any object with them works.
    """
    features = getattr(model, "features", "q,qd,qdd")
    n_joints = getattr(model, "n_joints_", None)
    if getattr(model, "forests_", None) is not None:
        return CompiledForest(model.forests_, features, n_joints)
    if getattr(model, "svrs_", None) is not None:
        return FastKernelModel.from_svrs(
            model.scaler_, model.svrs_, features,
            getattr(model, "target_mean_", None), getattr(model, "target_scale_", None),
            n_joints,
        )
    if getattr(model, "L_", None) is not None and getattr(model, "alpha_", None) is not None:
        return CompiledGaussianProcess(model)
    raise TypeError(
        f"no fast predictor for {type(model).__name__}: expected a fitted model with "
        "forests_ (random forest), scaler_ and svrs_ (SVR) or L_ and alpha_ (GPR)"
    )
