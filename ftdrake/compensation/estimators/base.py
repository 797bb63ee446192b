"""The contract every compensator follows (scikit-learn's estimator API).

A compensator maps joint states ``X = [q, q̇, q̈]`` (N × 3n) to the wrench the sensor reads
without contact (N × k targets; k = 6 for a wrench, or n for joint torques on other data).
``X`` may carry the sensor's temperature (°C) as one more, last column, ``[q, q̇, q̈, T]``
(N × (3n + 1); a width of 3n + 1 is never a joint layout, so it is unambiguous): every
compensator then uses it as a feature (the physics model as linear per-axis zero-drift
coefficients). Subclasses implement ``_fit(Z, Y)`` and ``_predict(Z)`` on the already
selected feature columns ``Z`` (with T appended last when present) and 2-D targets ``Y``;
everything shared (validation, the feature set, the training ranges used for out-of-domain
checks) lives here.

The protocol a compensator follows to run in a control loop and leave Python:

* ``provides_std`` – whether ``predict_std`` gives a predictive standard deviation.
* ``std_includes_noise`` – whether that std is of a new *reading* around the prediction
  (sensor noise included, so ``measured − predicted`` should fall within ±1.96 std 95 % of
  the time: physics, hybrid, GP with ``include_noise``), rather than a spread of the model
  alone (the forest's spread across trees, which is not calibrated).
* ``compiled_predictor()`` – ftdrake's compiled predictor (``predict(X)``, ``predict_one(x)``,
  equal to ``predict``), or None.
* ``row_predictor()`` – a function ``row (3n,) → (mean (k,), std (k,))`` without
  scikit-learn's input validation, for ``CompensatorSystem`` at the sensor rate; a model
  trained with the temperature takes ``row (3n + 1,)``, T last (physics, hybrid and forests
  have a compiled row path with it; SVR and GP go through ``predict``: their compiled kernels
  select features from the 3n joint layout only).
* ``fused_loop_update()`` – ``(update, arrays)``: a compiled update that runs a whole
  ``CompensatorSystem`` sample (input checks, q̈ estimate, prediction, compensated wrench) in
  one call, with the model's arrays it takes (:mod:`ftdrake.compensation.compiled.loop`), or
  None (the loop then calls ``row_predictor()``). Forests, the physics payload model and
  hybrids with a forest residual have one; it takes the 3n joint row only, so a model trained
  with the temperature (or an IMU) has none.
* ``robot_description()`` – the robot the model was trained on (physics and hybrid models
  carry it in their file), or None: the chain computes gravity at the sensor on it.
* ``onnx_parts()`` – what :mod:`ftdrake.compensation.files.onnx_export` writes as a graph, or
  TypeError for models that have no ONNX form.
* ``reading_to_model_frame()`` – None, or the 6 × 6 matrix T that turns ``measured −
  predicted`` (a wrench as the sensor reads it) into the model's frame S: the inverse of
  an identified mounting rotation or gain/cross-talk correction (physics and hybrid).
  ``CompensatorSystem`` applies it to the external wrench.

:mod:`..contract` declares this protocol (``LoopModel``) and checks a model against it once.

Parameters are declared and validated the scikit-learn way: each class's
``_parameter_constraints`` (``sklearn.utils._param_validation``'s ``Interval``,
``StrOptions``, ...) is checked at the start of ``fit``, and a value they refuse raises
:class:`ParameterError` naming the parameter and what it may be.

A new compensator is one module (a subclass, with its own ``make`` and train options when the
registry's defaults do not build it) and one entry in
:mod:`ftdrake.compensation.estimators.registry`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils._param_validation import InvalidParameterError, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from ...errors import ConfigError
from ..compiled.forest import FlatForest, forest_accumulate_with_std
from ..features import (  # describe_nonfinite: also taken from here
    FEATURE_SETS,
    check_feature_set,
    describe_nonfinite,
    joints_in_layout,
    select_features,
)


class ParameterError(ConfigError, InvalidParameterError):
    """A compensator's parameter holds a value its ``_parameter_constraints`` refuse:
    scikit-learn's InvalidParameterError (a ValueError), and a ConfigError for ftdrake's
    command line."""


class Compensator(RegressorMixin, BaseEstimator):
    """Base class: predicts internal wrench (or joint torques) from ``[q, q̇, q̈]``.

    Parameters
    ----------
    features : {"q", "q,qd", "q,qd,qdd"}
        Which blocks of the ``[q, q̇, q̈]`` layout the model uses.

    Fitted attributes
    -----------------
    n_features_in_ : int       3n, or 3n + 1 with the temperature column
    n_joints_ : int
    temperature_in_ : bool     whether X's last column is the sensor temperature (°C)
    n_outputs_ : int
    input_min_, input_max_ : (3n,) arrays, the training range of every input column
    wrench_delay_s_ : float    s, the delay of the targets' stream behind the joint states that
                               the caller corrected in the training rows (``fit``'s
                               `wrench_delay_s`; 0.0 when none was); the runtime chain
                               applies it live as a delay line on the joint state
    """

    #: True for models whose ``predict_std`` returns a real standard deviation.
    provides_std = False
    #: True when ``predict_std`` is the std of a new reading (noise included; see above).
    std_includes_noise = False
    # Defaults of fitted attributes that models saved before them lack (the loop contract,
    # :mod:`..contract`): no temperature input; the wrench stream in step with the joints.
    temperature_in_ = False
    wrench_delay_s_ = 0.0
    #: What each parameter may be; subclasses extend it (``{**Compensator._parameter_
    #: constraints, ...}``) with one entry per parameter of theirs.
    _parameter_constraints: ClassVar[dict] = {"features": [StrOptions(set(FEATURE_SETS))]}

    def __init__(self, features: str = "q,qd,qdd"):
        self.features = features

    # -- the sklearn API -------------------------------------------------------------------
    def fit(self, X, y, *, wrench_delay_s: float | None = None):
        """Fits on rows `X` (N, 3n) ``[q, q̇, q̈]`` (and the temperature, °C, as a last column)
        and targets `y` (N,) or (N, k). `wrench_delay_s` (s): how much later the targets'
        stream was than the joint states, already corrected in `X`, `y` by the caller
        (:func:`~ftdrake.data.stream_delay.align_training_data`); kept as
        ``wrench_delay_s_`` for the loop, which must apply the same correction live."""
        self._validate_params()
        check_feature_set(self.features)
        delay = 0.0 if wrench_delay_s is None else float(wrench_delay_s)
        if not np.isfinite(delay):
            raise ValueError(f"wrench_delay_s must be a finite number of seconds; got "
                             f"{wrench_delay_s!r}")
        X, y = validate_data(
            self, X, y, multi_output=True, y_numeric=True, ensure_all_finite=False,
            dtype=np.float64,
        )
        for arr, name in ((X, "X"), (y, "y")):
            message = describe_nonfinite(arr, name)
            if message:
                raise ValueError(message)
        self.temperature_in_ = bool(X.shape[1] % 3 == 1 and X.shape[1] > 1)
        self.n_joints_ = joints_in_layout(X.shape[1] - self.temperature_in_)
        self._y_was_1d = y.ndim == 1
        Y = y.reshape(len(y), -1)
        self.n_outputs_ = Y.shape[1]
        self.input_min_ = X.min(axis=0)
        self.input_max_ = X.max(axis=0)
        self.wrench_delay_s_ = delay
        self._fit(self._select(X), Y)
        return self

    def _validate_params(self) -> None:
        """The parameters against ``_parameter_constraints``; a ParameterError naming the
        first one they refuse."""
        try:
            super()._validate_params()
        except InvalidParameterError as e:
            raise ParameterError(str(e)) from None

    def predict(self, X):
        Y = self._predict(self._validated_features(X))
        return Y.ravel() if self._y_was_1d else Y

    def predict_std(self, X):
        """Predictive standard deviation per output; zeros for models that give none."""
        Z = self._validated_features(X)
        std = self._predict_std(Z) if self.provides_std else np.zeros((len(Z), self.n_outputs_))
        return std.ravel() if self._y_was_1d else std

    def out_of_domain(self, X, margin: float = 0.0) -> np.ndarray:
        """Boolean per row: True where a used input lies outside the training range.

        `margin` widens each column's range by that fraction of its width. Only joint inputs
        count (a temperature column, if any, is not checked).
        """
        check_is_fitted(self)
        X = np.atleast_2d(np.asarray(X, dtype=float))
        used = select_features(X[:, :3 * self.n_joints_], self.features).shape[1]
        width = self.input_max_[:used] - self.input_min_[:used]
        lo = self.input_min_[:used] - margin * width
        hi = self.input_max_[:used] + margin * width
        Z = X[:, :used]
        return ((Z < lo) | (Z > hi)).any(axis=1)

    # -- the loop protocol ----------------------------------------------------------------
    def compiled_predictor(self):
        """ftdrake's compiled predictor of this fitted model, or None when it has none."""

    def row_predictor(self):
        """A function ``row (3n,) [q, q̇, q̈] → (mean (k,), std (k,))`` for control loops.

        It skips scikit-learn's input validation (which costs more than a compiled forest);
        the caller passes finite rows of the full layout (with the temperature, °C, as one
        more, last entry for a model trained with it). The std is zeros for models without
        ``provides_std``. Uses the compiled predictor when there is one.
        """
        check_is_fitted(self)
        if getattr(self, "temperature_in_", False):
            return temperature_row_predictor(self)
        compiled = self.compiled_predictor()
        if compiled is None:
            return generic_row_predictor(self)
        if hasattr(compiled, "predict_one_with_std"):
            return compiled.predict_one_with_std
        zeros = np.zeros(self.n_outputs_)
        return lambda row: (compiled.predict_one(row), zeros)

    def fused_loop_update(self):
        """None: this model has no fused loop update (see the module docstring)."""

    def reading_to_model_frame(self):
        """None: this model's readings are in S already (see the module docstring)."""

    def payload_reading_map(self):
        """K = T·M (6 × 6): how a wrench acting at the sensor (in S, about So) shows in the
        compensated wrench ``T·(measured − predicted)``, for a model with a
        ``reading_matrix()`` M (T: :meth:`reading_to_model_frame`); None when it is the
        identity or the model has no M. With a cross-talk identified in free motion it is
        ``R⁻¹·(I + E)·R`` (R the mounting rotation on forces and torques): the bias tracker
        reads a grasped payload through it, as the model reads the tool."""
        reading_matrix = getattr(self, "reading_matrix", None)
        if reading_matrix is None:
            return None
        M = reading_matrix()
        T = self.reading_to_model_frame()
        K = M if T is None else T @ M
        return None if np.allclose(K, np.eye(6), rtol=0.0, atol=1e-12) else K

    def robot_description(self):
        """The RobotDescription this model was trained on, or None (a model of joint states
        alone, e.g. a forest, knows no robot)."""

    def onnx_parts(self):
        """The compiled form :func:`~ftdrake.compensation.files.onnx_export.build_onnx` writes."""
        raise TypeError(
            f"{type(self).__name__} has no ONNX export; forests and SVRs have one"
        )

    # -- subclass hooks -------------------------------------------------------------------
    def _fit(self, Z: np.ndarray, Y: np.ndarray) -> None:
        raise NotImplementedError

    def _predict(self, Z: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _predict_std(self, Z: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    # -- helpers ----------------------------------------------------------------------------
    def _validated_features(self, X) -> np.ndarray:
        check_is_fitted(self)
        shape = getattr(X, "shape", None)  # not np.shape: array-likes may refuse it
        width = shape[-1] if shape is not None and len(shape) == 2 else None
        if getattr(self, "temperature_in_", False) and width == 3 * self.n_joints_:
            raise ValueError(
                f"{type(self).__name__} was trained with the sensor temperature (°C) as the last "
                f"column of X ([q, q̇, q̈, T], {3 * self.n_joints_ + 1} columns); this X has no "
                "temperature column")
        X = validate_data(self, X, reset=False, ensure_all_finite=False, dtype=np.float64)
        message = describe_nonfinite(X, "X")
        if message:
            raise ValueError(message.replace("before fitting", "before predicting"))
        return self._select(X)

    def _select(self, X) -> np.ndarray:
        """The used feature columns of X, with the temperature column last if X has one."""
        n = 3 * self.n_joints_
        Z = select_features(X[:, :n], self.features)
        if getattr(self, "temperature_in_", False):
            Z = np.hstack([Z, X[:, n:n + 1]])
        return Z

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = True
        return tags


def temperature_row_predictor(model):
    """``row (3n + 1,) [q, q̇, q̈, T] → (mean, std)`` for a model trained with the temperature.

    ftdrake's compiled predictors take the 3n joint layout and select their features from it,
    so a temperature model cannot use them as they are. A forest's flattened trees (its
    ``onnx_parts()``) index the selected features with T as the last one: the compiled walk
    runs on ``[selected features, T]`` (equal to ``predict`` to round-off). Any other model
    goes through ``predict`` (:func:`generic_row_predictor`).
    """
    try:
        flat = model.onnx_parts()
    except (TypeError, ValueError, AttributeError):
        flat = None
    used = check_feature_set(model.features) * int(model.n_joints_)
    if not isinstance(flat, FlatForest) or flat.n_inputs != used + 1 \
            or flat.n_outputs != int(model.n_outputs_):
        return generic_row_predictor(model)
    arrays = (flat.nodes, flat.leaf_values, flat.trees, flat.n_trees)
    k = flat.n_outputs

    def predict(row):
        z = np.empty(used + 1)
        z[:used] = row[:used]
        z[used] = row[-1]
        mean, std = np.empty(k), np.empty(k)
        forest_accumulate_with_std(z, *arrays, mean, std)
        return mean, std

    return predict


def generic_row_predictor(model):
    """``row → (mean, std)`` through ``predict`` (and ``predict_std``): any fitted model."""
    zeros = np.zeros(int(model.n_outputs_))
    has_std = bool(getattr(model, "provides_std", False))

    def predict(row):
        X = row[None, :]
        mean = np.asarray(model.predict(X), dtype=float).reshape(-1)
        std = np.asarray(model.predict_std(X), dtype=float).reshape(-1) if has_std else zeros
        return mean, std

    return predict
