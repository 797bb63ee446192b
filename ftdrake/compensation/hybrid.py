"""Physics + learned residual: the payload model explains gravity and inertia, a learned model
(forest or GP) the rest — cable pull, cross-talk, anything the rigid model misses.

Physics extrapolates (it is right wherever the tool is a rigid body) and needs little data;
the residual learner only has to capture small, smooth effects, so it needs less data than a
black box learning the whole wrench.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import clone

from .base import Compensator
from .forest import RandomForestCompensator
from .physics import PhysicsPayloadCompensator


class HybridCompensator(Compensator):
    """``predict = physics.predict + residual.predict``.

    Parameters
    ----------
    physics : a PhysicsPayloadCompensator (default: dynamic, ftdrake's arm).
    residual : any compensator (default: RandomForestCompensator on ``q``).
    features : always "q,qd,qdd" (the parts select their own features).

    Fitted attributes: ``physics_``, ``residual_`` (fitted clones).
    """

    def __init__(self, physics=None, residual=None, features="q,qd,qdd"):
        super().__init__(features=features)
        self.physics = physics
        self.residual = residual

    @property
    def provides_std(self) -> bool:
        part = getattr(self, "residual_", None) or self.residual
        return bool(getattr(part, "provides_std", False))

    def _fit(self, Z, Y):
        if self.features != "q,qd,qdd":
            raise ValueError("HybridCompensator takes features='q,qd,qdd'; its parts select")
        physics = self.physics if self.physics is not None else PhysicsPayloadCompensator()
        residual = self.residual if self.residual is not None else RandomForestCompensator(
            features="q", min_samples_leaf=5, random_state=0)
        self.physics_ = clone(physics).fit(Z, Y)
        self.residual_ = clone(residual).fit(Z, Y - self._physics(Z))

    def row_predictor(self):
        """Physics row plus residual row; the std is the residual's (physics gives none)."""
        physics = self.physics_.row_predictor()
        residual = self.residual_.row_predictor()

        def predict(row):
            internal, std = residual(row)
            return physics(row)[0] + internal, std

        return predict

    def _physics(self, Z):
        return np.asarray(self.physics_.predict(Z)).reshape(len(Z), -1)

    def _predict(self, Z):
        residual = np.asarray(self.residual_.predict(Z)).reshape(len(Z), -1)
        return self._physics(Z) + residual

    def _predict_std(self, Z):
        return np.asarray(self.residual_.predict_std(Z)).reshape(len(Z), -1)
