"""Support-vector-regression compensator: the study's second model.

As in the study, every input column is rescaled to [-1, 1] from its training minimum and
maximum, and one scikit-learn ``SVR`` is trained per target column.

Target scaling (a departure from the study, on by default): each target column is
standardised (zero mean, unit standard deviation) before the SVR sees it, and predictions
are mapped back. Why: SVR's ``epsilon`` (the half-width of the error tube that costs nothing)
and, through the loss, ``C`` are in target units. Wrench axes differ by two orders of
magnitude (forces of tens of N, torques of tenths of N·m), so with raw targets one ``epsilon``
either ignores the whole torque signal or is negligible for the forces, and one grid cannot
suit all six axes. Standardised, ``epsilon = 0.05`` means "5 % of this axis's standard
deviation" on every axis. ``scale_targets=False`` reproduces the study exactly.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from sklearn.preprocessing import MinMaxScaler
from sklearn.svm import SVR
from sklearn.utils._param_validation import StrOptions
from sklearn.utils.validation import check_is_fitted

from ..compiled.kernel import FastKernelModel
from .base import Compensator


class SVRCompensator(Compensator):
    """Predicts the internal wrench with one epsilon-SVR per target column.

    Parameters
    ----------
    features : {"q", "q,qd", "q,qd,qdd"}
        Which blocks of the ``[q, q̇, q̈]`` input layout the SVRs see.
    kernel : {"rbf", "linear", "poly", "sigmoid"}
    C : float
        Regularisation: weight of errors beyond the tube against flatness.
    gamma : float or {"scale", "auto"}
        Kernel coefficient for rbf/poly/sigmoid, in 1 / (scaled input)²; inputs are in [-1, 1].
    epsilon : float
        Half-width of the tube, in standardised target units if ``scale_targets`` else in the
        target's own units (N or N·m).
    degree : int
        Degree of the poly kernel.
    scale_targets : bool
        Standardise every target column before fitting (see the module docstring).

    Fitted attributes
    -----------------
    scaler_ : sklearn.preprocessing.MinMaxScaler
        Maps every used input column's training [min, max] to [-1, 1].
    svrs_ : list of sklearn.svm.SVR, one per target column.
    target_mean_, target_scale_ : (n_outputs,) arrays
        ``y = target_mean_ + target_scale_ * svr_output``; 0 and 1 if not ``scale_targets``.
    """

    #: The SVRs' parameters as scikit-learn's SVR declares them; the kernels ftdrake compiles.
    _parameter_constraints: ClassVar[dict] = {
        **Compensator._parameter_constraints,
        "kernel": [StrOptions({"rbf", "linear", "poly", "sigmoid"})],
        **{name: SVR._parameter_constraints[name] for name in ("C", "gamma", "epsilon",
                                                                "degree")},
        "scale_targets": ["boolean"],
    }

    def __init__(
        self,
        features: str = "q,qd,qdd",
        kernel: str = "rbf",
        C: float = 10.0,
        gamma: float | str = "scale",
        epsilon: float = 0.05,
        degree: int = 3,
        scale_targets: bool = True,
    ):
        self.features = features
        self.kernel = kernel
        self.C = C
        self.gamma = gamma
        self.epsilon = epsilon
        self.degree = degree
        self.scale_targets = scale_targets

    def _fit(self, Z: np.ndarray, Y: np.ndarray) -> None:
        self.scaler_ = MinMaxScaler(feature_range=(-1, 1)).fit(Z)
        Zs = self.scaler_.transform(Z)
        if self.scale_targets:
            self.target_mean_ = Y.mean(axis=0)
            std = Y.std(axis=0)
            # A constant column has nothing to learn; scale 1 keeps it finite.
            self.target_scale_ = np.where(std > 0, std, 1.0)
        else:
            self.target_mean_ = np.zeros(Y.shape[1])
            self.target_scale_ = np.ones(Y.shape[1])
        Ys = (Y - self.target_mean_) / self.target_scale_
        self.svrs_ = [self._new_svr().fit(Zs, Ys[:, j]) for j in range(Y.shape[1])]

    def compiled_predictor(self):
        """A :class:`~ftdrake.compensation.compiled.FastKernelModel` of the fitted SVRs."""
        check_is_fitted(self)
        return FastKernelModel.from_svrs(
            self.scaler_, self.svrs_, self.features, getattr(self, "target_mean_", None),
            getattr(self, "target_scale_", None), self.n_joints_,
        )

    def onnx_parts(self):
        return self.compiled_predictor()

    def _new_svr(self) -> SVR:
        return SVR(
            kernel=self.kernel,
            C=self.C,
            gamma=self.gamma,
            epsilon=self.epsilon,
            degree=self.degree,
        )

    def _predict(self, Z: np.ndarray) -> np.ndarray:
        Zs = self.scaler_.transform(Z)
        Ys = np.column_stack([svr.predict(Zs) for svr in self.svrs_])
        return self.target_mean_ + self.target_scale_ * Ys
