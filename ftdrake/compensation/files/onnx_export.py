"""Exports a fitted compensator as one ONNX graph, in double precision.

The graph takes ``X`` (N × 3n float64, the full ``[q, q̇, q̈]`` layout) and returns ``Y``
(N × k float64); feature selection and input scaling happen inside it, so a runtime needs
nothing else. ONNX Runtime reproduces scikit-learn's ``predict`` to 1e-9 relative (the tested
bound).

Why the graphs are built here rather than by ``skl2onnx``: its converters emit ai.onnx.ml
opset-3 ``TreeEnsembleRegressor`` / ``SVMRegressor``, whose outputs are float32 (≈1e-7
relative error; ONNX Runtime rejects the double variant of the former and lacks the latter for
double input). Here:

* Forests use ai.onnx.ml opset 5 ``TreeEnsemble``, which is double throughout. The input is
  first rounded to float32 and back (``Cast``, ``Cast``), because scikit-learn compares
  ``float32(x)`` with its thresholds; without it, rows within a float32 rounding of a threshold
  go the other way. ``TreeEnsemble`` gives each leaf one target only, so rather than copying
  a k-output tree k times, each tree returns the index of the leaf it reaches (exact in
  double); ``Gather`` fetches that leaf's values, ``ReduceSum`` adds up each forest's trees
  and ``Div`` averages.
* Kernel models (SVR) are written with standard double ops: ``Mul``/``Add`` (min-max scaling),
  the kernel (``Sub``, ``ReduceSum``, ``Exp``, ``MatMul``, ``Tanh``, ``Pow``), ``MatMul``
  with the dual coefficients.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from ...io import atomic_write_bytes
from ..compiled.forest import FlatForest, flatten_forests
from ..compiled.kernel import FastKernelModel
from ..compiled.rows import joints_for

OPSET = 21  # default domain
ML_OPSET = 5  # ai.onnx.ml: TreeEnsemble with double thresholds and outputs
IR_VERSION = 10  # the oldest that carries opset 21; ONNX Runtime ≥ 1.18 reads it


class _GraphBuilder:
    """Appends nodes and constants, naming every intermediate value uniquely."""

    def __init__(self):
        self.nodes: list[onnx.NodeProto] = []
        self.initializers: list[onnx.TensorProto] = []
        self._names = 0

    def _unique(self, name: str) -> str:
        self._names += 1
        return f"{name}_{self._names}"

    def const(self, array, name: str) -> str:
        name = self._unique(name)
        self.initializers.append(numpy_helper.from_array(np.asarray(array), name))
        return name

    def op(self, op_type: str, *inputs: str, output: str | None = None, **attributes) -> str:
        output = output or self._unique(op_type.lower())
        domain = "ai.onnx.ml" if op_type == "TreeEnsemble" else ""
        self.nodes.append(
            helper.make_node(op_type, list(inputs), [output], domain=domain, **attributes)
        )
        return output


def _forest_graph(g: _GraphBuilder, Z: str, flat: FlatForest) -> str:
    """Nodes computing the forest's prediction (N, k) from selected features Z (N, d)."""
    nodes, trees = flat.nodes, flat.trees
    n_trees, n_leaves = len(trees), len(flat.leaf_values)
    # A tree that is one leaf needs one interior node whose two branches reach that leaf.
    lone = np.flatnonzero(trees["root"] < 0)
    roots = trees["root"].astype(np.int64)
    roots[lone] = len(nodes) + np.arange(len(lone))
    left = np.concatenate([nodes["left"], trees["root"][lone]])  # child indices, as in fast.py
    right = np.concatenate([nodes["right"], trees["root"][lone]])
    # Leaves of tree t are numbered first_leaf[t] .. first_leaf[t+1]-1.
    leaf_tree = np.repeat(np.arange(n_trees), np.diff(np.append(trees["first_leaf"], n_leaves)))
    leaf_index = g.op(
        "TreeEnsemble",
        g.op("Cast", g.op("Cast", Z, to=TensorProto.FLOAT), to=TensorProto.DOUBLE),
        aggregate_function=1,  # SUM: each "target" t is tree t alone
        post_transform=0,
        n_targets=n_trees,
        tree_roots=roots.tolist(),
        nodes_featureids=np.concatenate([nodes["feature"], np.zeros(len(lone), int)]).tolist(),
        nodes_modes=numpy_helper.from_array(np.zeros(len(left), np.uint8)),  # BRANCH_LEQ
        nodes_splits=numpy_helper.from_array(
            np.concatenate([nodes["threshold"].astype(np.float64), np.zeros(len(lone))])
        ),
        nodes_truenodeids=np.where(left < 0, -1 - left, left).tolist(),
        nodes_trueleafs=(left < 0).astype(int).tolist(),
        nodes_falsenodeids=np.where(right < 0, -1 - right, right).tolist(),
        nodes_falseleafs=(right < 0).astype(int).tolist(),
        leaf_targetids=leaf_tree.tolist(),
        leaf_weights=numpy_helper.from_array(np.arange(n_leaves, dtype=np.float64)),
    )  # (N, n_trees)
    values = g.op(
        "Gather", g.const(flat.leaf_values, "leaf_values"),
        g.op("Cast", leaf_index, to=TensorProto.INT64), axis=0,
    )  # (N, n_trees, width)
    # Sum each forest's trees (a run of trees with the same first column), keep its columns.
    # ReduceSum, not a 0/1 MatMul: ONNX Runtime fuses MatMul + Div-by-scalar into a float32
    # `alpha` attribute, a 1e-7 relative error.
    sums = []
    starts = np.flatnonzero(np.diff(trees["column"], prepend=-1))
    for start, stop in zip(starts, np.append(starts[1:], n_trees), strict=True):
        forest = g.op("Slice", values, g.const(np.array([start, 0]), "starts"),
                      g.const(np.array([stop, trees[start]["width"]]), "ends"),
                      g.const(np.array([1, 2]), "axes"))
        sums.append(g.op("ReduceSum", forest, g.const(np.array([1]), "axes"), keepdims=0))
    total = sums[0] if len(sums) == 1 else g.op("Concat", *sums, axis=1)
    return g.op("Div", total, g.const(flat.n_trees, "n_trees"))


def _kernel_graph(g: _GraphBuilder, Z: str, model: FastKernelModel) -> str:
    """Nodes computing the kernel model's prediction (N, k) from selected features Z (N, d)."""
    Z = g.op("Add", g.op("Mul", Z, g.const(model.input_scale, "input_scale")),
             g.const(model.input_offset, "input_offset"))
    if model.clip is not None:
        low, high = (g.const(np.float64(v), "clip") for v in model.clip)
        Z = g.op("Clip", Z, low, high)
    total = g.const(model.intercept, "intercept")
    for e in model.expansions:
        if e.kernel == "rbf":
            diff = g.op("Sub", g.op("Unsqueeze", Z, g.const(np.array([1]), "axes")),
                        g.const(e.points, "points"))  # (N, m, d)
            sq_dist = g.op("ReduceSum", g.op("Mul", diff, diff), g.const(np.array([2]), "axes"),
                           keepdims=0)
            K = g.op("Exp", g.op("Mul", sq_dist, g.const(np.float64(-e.gamma), "neg_gamma")))
        elif e.kernel == "linear":
            K = g.op("MatMul", Z, g.const(e.points.T.copy(), "points_t"))
        else:
            # gamma goes into the constant: ONNX Runtime would fuse a Mul after the MatMul
            # into a float32 `alpha` attribute (1e-7 relative error).
            K = g.op("Add", g.op("MatMul", Z, g.const(e.gamma * e.points.T, "gamma_points_t")),
                     g.const(np.float64(e.coef0), "coef0"))
            K = (g.op("Pow", K, g.const(np.float64(e.degree), "degree"))
                 if e.kernel == "poly" else g.op("Tanh", K))
        total = g.op("Add", total, g.op("MatMul", K, g.const(e.weights, "weights")))
    return g.op("Add", g.const(model.target_mean, "target_mean"),
                g.op("Mul", g.const(model.target_scale, "target_scale"), total))


def _given(name: str, given, own):
    """The model's own value of `name`, checked against the one given (either may be None)."""
    if given is not None and own is not None and given != own:
        raise ValueError(f"{name}={given!r} was given, but the model has {name}={own!r}")
    return own if own is not None else given


#: How each ONNX form is written: the forms a compensator's ``onnx_parts()`` returns.
_GRAPHS = {FlatForest: _forest_graph, FastKernelModel: _kernel_graph}


def _as_parts(m, n_joints, features):
    """(ONNX form, n_joints, features) from whatever was passed: a compensator or a compiled
    predictor (they say what they export, ``onnx_parts()``), an ONNX form itself, a tuple of
    a scaler and SVRs, or fitted forests."""
    own_features = getattr(m, "features", None)
    own_joints = getattr(m, "n_joints_", getattr(m, "n_joints", None))
    if type(m) in _GRAPHS:
        part = m
    elif hasattr(m, "onnx_parts"):  # the compensator protocol (TypeError: no ONNX form)
        part = m.onnx_parts()
    else:
        own_features = own_joints = None
        if features is None:
            raise ValueError("pass features= for a model without a `features` attribute")
        if isinstance(m, tuple) and len(m) in (2, 4):  # (scaler, svrs[, target_mean, scale])
            part = FastKernelModel.from_svrs(m[0], m[1], features, *m[2:], n_joints=n_joints)
        else:
            part = flatten_forests(getattr(m, "forests_", m))  # ValueError if not forests
    features = _given("features", features, own_features)
    if features is None:
        raise ValueError("pass features= for a model without a `features` attribute")
    n_joints = _given("n_joints", n_joints, own_joints)
    return part, joints_for(part.n_inputs, features, n_joints), features


def build_onnx(model_or_parts, n_joints: int | None = None, features: str | None = None):
    """The ONNX ModelProto of a fitted model; see :func:`export_onnx` for the arguments."""
    part, n_joints, features = _as_parts(model_or_parts, n_joints, features)
    g = _GraphBuilder()
    Z = "X"
    if part.n_inputs != 3 * n_joints:
        Z = g.op("Slice", "X", g.const(np.array([0]), "starts"),
                 g.const(np.array([part.n_inputs]), "ends"), g.const(np.array([1]), "axes"))
    g.op("Identity", _GRAPHS[type(part)](g, Z, part), output="Y")
    graph = helper.make_graph(
        g.nodes, "ftdrake_compensator",
        [helper.make_tensor_value_info("X", TensorProto.DOUBLE, ["N", 3 * n_joints])],
        [helper.make_tensor_value_info("Y", TensorProto.DOUBLE, ["N", part.n_outputs])],
        initializer=g.initializers,
    )
    model = helper.make_model(
        graph, ir_version=IR_VERSION, producer_name="ftdrake",
        opset_imports=[helper.make_opsetid("", OPSET), helper.make_opsetid("ai.onnx.ml", ML_OPSET)],
    )
    helper.set_model_props(model, {"features": features, "n_joints": str(n_joints),
                                   "input_layout": "[q, qd, qdd]"})
    onnx.checker.check_model(model)
    return model


def export_onnx(
    model_or_parts, path, n_joints: int | None = None, features: str | None = None
) -> Path:
    """Writes a fitted model as one ONNX graph ``X`` (N × 3n) → ``Y`` (N × k), atomically.

    model_or_parts: a fitted ``RandomForestCompensator`` or ``SVRCompensator`` (or any object
        with ``forests_`` / ``scaler_`` + ``svrs_``), a CompiledForest or FastKernelModel, a
        fitted regression forest or list of forests, or a tuple ``(scaler, svrs)`` /
        ``(scaler, svrs, target_mean, target_scale)``.
    n_joints, features: taken from the model when it has them (and then checked against
        these if given); features is needed for bare forests and SVRs, n_joints is inferred.
    The file is written to a temporary file next to `path` and renamed over it, so a reader
    never sees a partial file. Returns `path`.
    """
    model = build_onnx(model_or_parts, n_joints, features)
    path = Path(path)
    atomic_write_bytes(path, model.SerializeToString())
    return path
