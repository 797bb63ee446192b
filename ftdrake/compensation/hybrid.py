"""Physics + learned residual: the payload model explains gravity and inertia, a learned model
(forest or GP) the rest — cable pull, cross-talk, anything the rigid model misses.

Physics extrapolates (it is right wherever the tool is a rigid body) and needs little data;
the residual learner only has to capture small, smooth effects, so it needs less data than a
black box learning the whole wrench.

Predictive std: the physics part's parameter uncertainty and the residual's uncertainty,
added as independent variances,

    std² = ‖B(x) F‖²  (physics parameters, see PhysicsPayloadCompensator)
         + the residual's predictive variance of a reading (a GP with ``include_noise``), or,
           for a residual whose std is not that (a forest: spread across trees, not
           calibrated), its cross-validated error variance per axis (``residual_noise_var_``:
           the residual model refitted on alternate blocks of rows and scored on the others)

The second term includes the sensor noise; the physics part's own noise term is left out (the
residual model explains part of what it holds). Independence is an approximation: the
residual was fitted to the physics part's errors.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import clone
from sklearn.utils.validation import check_is_fitted

from .base import Compensator
from .compiled.forest import CompiledForest
from .compiled.hybrid import CompiledHybrid, hybrid_row
from .compiled.loop import compensate_with_hybrid
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

    Fitted attributes: ``physics_``, ``residual_`` (fitted clones), ``residual_noise_var_``
    (6,) the residual's cross-validated error variance per axis (NaN when the residual's own
    std is used).
    """

    provides_std = True
    std_includes_noise = True
    #: Alternating blocks of rows in the cross-fit that estimates ``residual_noise_var_``.
    CROSS_FIT_BLOCKS = 10

    def __init__(self, physics=None, residual=None, features="q,qd,qdd", identification=None,
                 prior=None):
        super().__init__(features=features)
        self.physics = physics
        self.residual = residual
        self.identification = identification
        self.prior = prior

    def _fit(self, Z, Y):
        if self.features != "q,qd,qdd":
            raise ValueError("HybridCompensator takes features='q,qd,qdd'; its parts select")
        physics = self.physics if self.physics is not None else PhysicsPayloadCompensator()
        physics = clone(physics).set_params(**{
            k: v for k, v in (("identification", self.identification), ("prior", self.prior))
            if v is not None})
        residual = self.residual if self.residual is not None else default_residual()
        self.physics_ = clone(physics).fit(Z, Y)
        target = Y - self._physics(Z)
        self.residual_ = clone(residual).fit(Z, target)
        self.residual_noise_var_ = np.full(Y.shape[1], np.nan)
        if not self._residual_std_is_calibrated():
            self.residual_noise_var_ = self._cross_validated_variance(residual, Z, target)

    def _residual_std_is_calibrated(self) -> bool:
        part = self.residual_
        return bool(getattr(part, "provides_std", False)
                    and getattr(part, "std_includes_noise", False))

    def _cross_validated_variance(self, residual, Z, target):
        """Per-axis mean squared error of the residual model on rows it was not fitted on:
        rows in `CROSS_FIT_BLOCKS` contiguous blocks, fitted on the even ones and scored on
        the odd ones and the other way round (contiguous: neighbouring samples of a time
        series are nearly copies of each other)."""
        block = (np.arange(len(Z)) * self.CROSS_FIT_BLOCKS) // max(len(Z), 1) % 2 == 0
        errors = np.empty_like(target)
        for train in (block, ~block):
            if train.sum() < 2 or (~train).sum() < 1:
                return np.mean(target ** 2, axis=0)
            part = clone(residual).fit(Z[train], target[train])
            errors[~train] = target[~train] - np.asarray(part.predict(Z[~train])).reshape(
                (~train).sum(), -1)
        return np.mean(errors ** 2, axis=0)

    def identified(self) -> dict:
        """The physics part's identified parameters (``physics_.identified()``)."""
        return self.physics_.identified()

    def summary(self) -> str:
        """The physics part's identified parameters, as lines a user reads."""
        return self.physics_.summary()

    def reading_to_model_frame(self):
        """The physics part's (the residual is learned in the reading's frame too)."""
        return self.physics_.reading_to_model_frame()

    def compiled_predictor(self):
        """A :class:`~ftdrake.compensation.compiled.hybrid.CompiledHybrid` (payload model
        and residual forest in one numba call per row, mean and std) when the residual's
        compiled predictor is a forest and its std is the cross-validated error variance (the
        default residual); None otherwise (a GP residual, a temperature column)."""
        check_is_fitted(self)
        if getattr(self, "temperature_in_", False) or self._residual_std_is_calibrated():
            return None
        residual = getattr(self.residual_, "compiled_predictor", lambda: None)()
        if not isinstance(residual, CompiledForest):
            return None
        payload = self.physics_.packed_row(noise_var=np.nan_to_num(self._noise_var()))
        return CompiledHybrid(payload, residual.flat, self.n_joints_)

    def fused_loop_update(self):
        """The compiled hybrid's loop update
        (:func:`~ftdrake.compensation.compiled.loop.compensate_with_hybrid`) and its arrays,
        when there is a compiled predictor (:meth:`compiled_predictor`); else None."""
        compiled = self.compiled_predictor()
        return None if compiled is None else (compensate_with_hybrid, compiled.arrays)

    def row_predictor(self):
        """Physics row plus residual row; the std combines both (module docstring). One
        compiled call per row with the compiled predictor (a forest residual), else the two
        parts' row predictors combined in numpy."""
        compiled = self.compiled_predictor()
        if compiled is not None:
            arrays = compiled.arrays

            def fused(row):
                mean, std = np.empty(6), np.empty(6)
                hybrid_row(row, *arrays, mean, std)
                return mean, std

            return fused
        physics = self.physics_.row_predictor(include_noise=False)
        residual = self.residual_.row_predictor()
        calibrated = self._residual_std_is_calibrated()
        noise_var = np.nan_to_num(self._noise_var())

        def predict(row):
            mean, physics_std = physics(row)
            internal, residual_std = residual(row)
            var = physics_std * physics_std + (residual_std * residual_std if calibrated
                                               else noise_var)
            return mean + internal, np.sqrt(var)

        return predict

    def _noise_var(self):
        var = getattr(self, "residual_noise_var_", None)
        if var is None:  # a model file from before the hybrid had a std: the physics part's
            var = np.asarray(self.physics_.residual_rms_) ** 2
        return np.asarray(var, dtype=float)

    def _physics(self, Z):
        return np.asarray(self.physics_.predict(Z)).reshape(len(Z), -1)

    def _predict(self, Z):
        residual = np.asarray(self.residual_.predict(Z)).reshape(len(Z), -1)
        return self._physics(Z) + residual

    def _predict_std(self, Z):
        var = self.physics_._variance(self.physics_._select(Z), include_noise=False)
        if self._residual_std_is_calibrated():
            var = var + np.asarray(self.residual_.predict_std(Z)).reshape(len(Z), -1) ** 2
        else:
            var = var + self._noise_var()
        return np.sqrt(var)


def default_residual() -> RandomForestCompensator:
    """The residual a hybrid gets by default: one multi-output forest of 50 trees on ``q``,
    at least 40 training rows in a leaf.

    Why not the study's per-axis forests: the residual is small and smooth (cable, cross-talk,
    what the rigid model misses), one forest predicts all six axes of it, and the hybrid must
    run in the loop, where one multi-output forest of 50 trees costs a fraction of six
    per-axis forests of 100 (``benchmarks/compensator_latency.py`` measures both).

    Why 40 rows a leaf (5 before): a smooth residual needs no finer leaves, and the file is a
    quarter of the nodes. On the demo's data (45,500 rows, ``benchmarks/model_size.py``) the
    hybrid's file went from 27.8 MB to 3.5 MB with held-out errors equal or lower on every
    axis (Fx..Tz 2.29, 2.24, 1.74, 1.88, 2.84, 1.79 σ with 5 rows a leaf; 2.28, 2.24, 1.75,
    1.76, 2.77, 1.73 σ with 40). The size grows with the training rows (``--max-rows`` bounds
    it).
    """
    return RandomForestCompensator(features="q", per_output=False, n_estimators=50,
                                   min_samples_leaf=40, random_state=0)
