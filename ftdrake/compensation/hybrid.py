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
    residual : any compensator (default: :func:`default_residual`, a forest on ``q``).
    features : always "q,qd,qdd" (the parts select their own features).
    identification, prior : if not None, override the physics part's (see
        :class:`~.physics.PhysicsPayloadCompensator`), so that a registry default or a config
        reaches it.

    Fitted attributes: ``physics_``, ``residual_`` (fitted clones).
    """

    def __init__(self, physics=None, residual=None, features="q,qd,qdd", identification=None,
                 prior=None):
        super().__init__(features=features)
        self.physics = physics
        self.residual = residual
        self.identification = identification
        self.prior = prior

    @property
    def provides_std(self) -> bool:
        part = getattr(self, "residual_", None) or self.residual
        return bool(getattr(part, "provides_std", False))

    def _fit(self, Z, Y):
        if self.features != "q,qd,qdd":
            raise ValueError("HybridCompensator takes features='q,qd,qdd'; its parts select")
        physics = self.physics if self.physics is not None else PhysicsPayloadCompensator()
        physics = clone(physics).set_params(**{
            k: v for k, v in (("identification", self.identification), ("prior", self.prior))
            if v is not None})
        residual = self.residual if self.residual is not None else default_residual()
        self.physics_ = clone(physics).fit(Z, Y)
        self.residual_ = clone(residual).fit(Z, Y - self._physics(Z))

    def identified(self) -> dict:
        """The physics part's identified parameters (``physics_.identified()``)."""
        return self.physics_.identified()

    def summary(self) -> str:
        """The physics part's identified parameters, as lines a user reads."""
        return self.physics_.summary()

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


def default_residual() -> RandomForestCompensator:
    """The residual a hybrid gets by default: one multi-output forest of 50 trees on ``q``.

    Why not the study's per-axis forests: the residual is small and smooth (cable, cross-talk,
    what the rigid model misses), one forest predicts all six axes of it, and the hybrid must
    run in the loop: per-axis forests of 100 trees cost ~45 µs per row, one multi-output
    forest of 50 trees ~4 µs (``benchmarks/compensator_latency.py``).
    """
    return RandomForestCompensator(features="q", per_output=False, n_estimators=50,
                                   min_samples_leaf=5, random_state=0)
