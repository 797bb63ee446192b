"""Random-forest compensator: the study's best model for the internal wrench.

The study trains one scikit-learn random forest per wrench axis ("as the output is limited to
a single scalar value, a separate model has to be trained for each output dimension"). That is
the default here (``per_output=True``); ``per_output=False`` trains one multi-output forest
whose trees split on all axes at once (smaller and faster, usually a little less accurate).

``predict_std`` is the standard deviation of the trees' predictions around the forest's mean
(per output). It is **not a calibrated predictive uncertainty**: it measures how much the
bootstrapped trees disagree, not the sensor noise, and it shrinks where the trees share their
leaves' training rows. How much of held-out data ±1.96 of it covers depends on the data, not
on a probability model. Use it to rank rows (where the forest is unsure), not as an error bar;
the GP, physics and hybrid models give calibrated ones.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from sklearn.ensemble import RandomForestRegressor
from sklearn.utils.validation import check_is_fitted

from ..compiled.forest import CompiledForest, flatten_forests
from ..compiled.loop import compensate_with_forest
from .base import Compensator


class RandomForestCompensator(Compensator):
    """Predicts the internal wrench with random forests of regression trees.

    ``predict_std``: the spread across trees (not calibrated; see the module docstring).

    Parameters
    ----------
    features : {"q", "q,qd", "q,qd,qdd"}
        Which blocks of the ``[q, q̇, q̈]`` input layout the forests see.
    n_estimators : int
        Trees per forest.
    max_features : int or float
        Features tried at each split: an int is a count (the study's grid, 2..21), a float a
        fraction of the used features (1.0 = all, scikit-learn's default for regression).
    min_samples_leaf : int
        Smallest number of training rows in a leaf; larger values smooth the prediction.
    per_output : bool
        True: one forest per target column (as in the study). False: one multi-output forest.
    random_state : int, RandomState or None
        Seed of the bootstrap and feature sampling.
    n_jobs : int or None
        Threads used by each forest to fit and predict.

    Fitted attributes
    -----------------
    forests_ : list of sklearn.ensemble.RandomForestRegressor
        ``n_outputs_`` single-output forests if ``per_output`` else one multi-output forest.
    feature_importances_ : (n_outputs, n_used_features) array
        Impurity-based importance of each used input column, per target column.
    """

    #: The spread across trees; not a calibrated std of a reading (``std_includes_noise``).
    provides_std = True
    #: The forests' parameters as scikit-learn's RandomForestRegressor declares them.
    _parameter_constraints: ClassVar[dict] = {
        **Compensator._parameter_constraints,
        **{name: RandomForestRegressor._parameter_constraints[name] for name in (
            "n_estimators", "max_features", "min_samples_leaf", "random_state", "n_jobs")},
        "per_output": ["boolean"],
    }

    def __init__(
        self,
        features: str = "q,qd,qdd",
        n_estimators: int = 100,
        max_features: float = 1.0,  # or an int count
        min_samples_leaf: int = 2,
        per_output: bool = True,
        random_state=None,
        n_jobs: int | None = None,
    ):
        self.features = features
        self.n_estimators = n_estimators
        self.max_features = max_features
        self.min_samples_leaf = min_samples_leaf
        self.per_output = per_output
        self.random_state = random_state
        self.n_jobs = n_jobs

    def compiled_predictor(self):
        """A :class:`~ftdrake.compensation.compiled.CompiledForest` of the fitted forests."""
        check_is_fitted(self)
        return CompiledForest(self.forests_, self.features, self.n_joints_)

    def fused_loop_update(self):
        """The compiled forest's loop update
        (:func:`~ftdrake.compensation.compiled.loop.compensate_with_forest`) and its arrays;
        None for a model trained with the temperature."""
        check_is_fitted(self)
        if getattr(self, "temperature_in_", False):
            return None
        return compensate_with_forest, self.compiled_predictor().arrays

    def onnx_parts(self):
        check_is_fitted(self)
        return flatten_forests(self.forests_)

    def _new_forest(self) -> RandomForestRegressor:
        return RandomForestRegressor(
            n_estimators=self.n_estimators,
            max_features=self.max_features,
            min_samples_leaf=self.min_samples_leaf,
            random_state=self.random_state,
            n_jobs=self.n_jobs,
        )

    def _fit(self, Z: np.ndarray, Y: np.ndarray) -> None:
        if self.per_output:
            # 1-D targets: a single-output forest, and no column-vector warning from sklearn.
            self.forests_ = [self._new_forest().fit(Z, Y[:, j]) for j in range(Y.shape[1])]
        else:
            self.forests_ = [self._new_forest().fit(Z, Y if Y.shape[1] > 1 else Y[:, 0])]

    def _predict(self, Z: np.ndarray) -> np.ndarray:
        if self.per_output:
            return np.column_stack([forest.predict(Z) for forest in self.forests_])
        return self.forests_[0].predict(Z).reshape(len(Z), -1)

    def _predict_std(self, Z: np.ndarray) -> np.ndarray:
        columns = []
        for forest in self.forests_:
            trees = np.stack([tree.predict(Z) for tree in forest.estimators_])
            columns.append(trees.reshape(len(trees), len(Z), -1).std(axis=0))
        return np.hstack(columns)

    @property
    def feature_importances_(self) -> np.ndarray:
        """(n_outputs, n_used_features); a multi-output forest's one ranking is repeated."""
        check_is_fitted(self)
        rows = [forest.feature_importances_ for forest in self.forests_]
        return np.tile(rows[0], (self.n_outputs_, 1)) if not self.per_output else np.vstack(rows)
