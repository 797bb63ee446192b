"""Physics + learned residual: the payload model explains gravity and inertia, a learned model
(forest or GP) the rest — cable pull, cross-talk, anything the rigid model misses.

Physics extrapolates (it is right wherever the tool is a rigid body) and needs little data;
the residual learner only has to capture small, smooth effects, so it needs less data than a
black box learning the whole wrench.

Predictive std: the physics part's parameter uncertainty and the residual's uncertainty,
added as independent variances,

    std² = c ‖B(x) F‖²  (physics parameters, see PhysicsPayloadCompensator; c = 1 until
           calibrated on held-out runs, ``domain_parameter_scale_``)
         + the residual's predictive variance of a reading (a GP with ``include_noise``: it
           grows to the GP's prior variance away from its data by itself), or, for a residual
           whose std is not that (a forest: spread across trees, not calibrated),
           w · σ²_in + (1 − w) · σ²_far + g² · d, with w the residual's support at the
           input and d its distance to the training inputs

and the prediction ``physics + w · residual`` (:mod:`.domain`): where the residual has seen
data (w ≈ 1) its error σ²_in (``residual_noise_var_``); away from it (w → 0) the hybrid falls
back to its physics part and to that part's own error σ²_far (``domain_far_var_``), which
grows by g² (``domain_growth_``: g) per unit of d as the model extrapolates. The weight is
exp(−(d/ℓ)²) of the distance d to the training inputs in the residual's standardised input
metric (``domain_distance``). Fitted alone, ℓ (``domain_length_``) and σ²_in come from the
cross-fit (the residual refitted on alternate blocks of rows and scored on the others, with
g = 0); calibrated on held-out runs that leave the training data
(:class:`~.domain_calibrated.DomainCalibratedHybrid`, which wraps a hybrid: on another log,
or on the runs of the training data farthest from the others, held out for it), ℓ and
g are fitted on them — and with ``in_domain="held_out"`` σ²_in (at least the residual's error
on its training rows) and c too.

The second term includes the sensor noise; the physics part's own noise term is left out (the
residual model explains part of what it holds). Independence is an approximation: the
residual was fitted to the physics part's errors.
"""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Integral
from typing import ClassVar

import numpy as np
from sklearn.base import clone
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from ..compiled.forest import CompiledForest
from ..compiled.hybrid import CompiledHybrid, hybrid_row
from ..compiled.loop import compensate_with_hybrid
from ..features import check_feature_set
from ..identification.consistent import PayloadPrior
from . import domain
from .arm import ArmDynamicsCompensator
from .base import Compensator
from .forest import RandomForestCompensator
from .physics import IDENTIFICATIONS, PhysicsPayloadCompensator


class HybridCompensator(Compensator):
    """``predict = physics.predict + residual.predict``.

    Parameters
    ----------
    physics : a PhysicsPayloadCompensator (default: dynamic, ftdrake's arm) on a wrench, or an
        :class:`~.arm.ArmDynamicsCompensator` on joint torques.
    residual : any compensator (default: :func:`default_residual`, a forest on ``q``, with a
        payload model; :func:`joint_torque_residual`, a forest on ``q, q̇, q̈``, with an arm
        model).
    features : always "q,qd,qdd" (the parts select their own features).
    identification, prior : if not None, override the physics part's (see
        :class:`~.physics.PhysicsPayloadCompensator`), so that a registry default or a config
        reaches it.
    support_points : the most training rows the residual's support keeps (every k-th row,
        :func:`.domain.fit_support`); None: :data:`.domain.SUPPORT_POINTS` with a payload
        model; with an arm model :data:`JOINT_TORQUE_SUPPORT_POINTS`, and at most every
        :data:`JOINT_TORQUE_SUPPORT_STRIDE`-th row.

    Fitted attributes: ``physics_``, ``residual_`` (fitted clones), ``residual_noise_var_``
    (6,) σ²_in, the residual's error variance per axis where it has data: cross-validated,
    or calibrated on held-out runs by :class:`~.domain_calibrated.DomainCalibratedHybrid`
    (NaN when the residual's own
    std is used); ``residual_training_var_`` (6,) its error on its own training rows, the
    least σ²_in a calibration gives; ``residual_cross_fit_var_`` (6,) its error on rows it
    was not fitted on (the cross-fit's, all distances; None for a residual with its own std),
    against ``domain_far_var_``, the physics part's error alone.
    """

    provides_std = True
    std_includes_noise = True
    #: Alternating blocks of rows in the cross-fit that estimates ``residual_noise_var_``.
    CROSS_FIT_BLOCKS = 10
    _parameter_constraints: ClassVar[dict] = {
        "physics": [HasMethods(["fit", "predict"]), None],  # the payload or arm model
        "residual": [HasMethods(["fit", "predict"]), None],
        "features": [StrOptions({"q,qd,qdd"})],  # the parts select their own
        "identification": [StrOptions(set(IDENTIFICATIONS)), None],
        "prior": [PayloadPrior, Mapping, None],
        "support_points": [Interval(Integral, 1, None, closed="left"), None],
    }

    def __init__(self, physics=None, residual=None, features="q,qd,qdd", identification=None,
                 prior=None, support_points=None):
        super().__init__(features=features)
        self.physics = physics
        self.residual = residual
        self.identification = identification
        self.prior = prior
        self.support_points = support_points

    def _fit(self, Z, Y):
        physics = self.physics if self.physics is not None else PhysicsPayloadCompensator()
        physics = clone(physics).set_params(**{
            k: v for k, v in (("identification", self.identification), ("prior", self.prior))
            if v is not None})
        residual = self._residual()
        self.physics_ = clone(physics).fit(Z, Y)
        target = Y - self._physics(Z)
        self.residual_ = clone(residual).fit(Z, target)
        self.residual_training_var_ = np.mean(
            (target - np.asarray(self.residual_.predict(Z)).reshape(target.shape)) ** 2, axis=0)
        self.residual_noise_var_ = np.full(Y.shape[1], np.nan)
        self.domain_far_var_ = np.mean(target ** 2, axis=0)
        self.domain_length_ = np.inf
        self.domain_growth_ = np.zeros(Y.shape[1])
        self.domain_excess_var_ = np.zeros(Y.shape[1])
        self.domain_parameter_scale_ = 1.0
        self.domain_support_ = domain.fit_support(self._domain_inputs(Z),
                                                  self._support_points(len(Z)))
        self.domain_calibration_ = None  # DomainCalibratedHybrid's record
        self.residual_cross_fit_var_ = None
        if not self._residual_std_is_calibrated():
            cross_fit = self._cross_fit(residual, Z, target)
            if cross_fit is None:
                self.residual_noise_var_ = np.mean(target ** 2, axis=0)
            else:
                self.residual_cross_fit_var_ = np.mean((cross_fit[1] - cross_fit[2]) ** 2,
                                                       axis=0)
                self.domain_length_, self.residual_noise_var_ = domain.fit_in_domain(
                    *cross_fit, self.domain_far_var_)

    def _on_joint_torques(self) -> bool:
        """Whether the physics part is the whole arm's torque model (the targets are joint
        torques, not a wrench)."""
        return isinstance(self.physics, ArmDynamicsCompensator)

    def _residual(self):
        """The residual to fit: the given one, else the default for the physics part."""
        if self.residual is not None:
            return self.residual
        return joint_torque_residual() if self._on_joint_torques() else default_residual()

    def _support_points(self, rows: int) -> int:
        """The most rows the support of `rows` training rows keeps."""
        points = getattr(self, "support_points", None)
        if points is not None:
            return int(points)
        if self._on_joint_torques():
            return min(JOINT_TORQUE_SUPPORT_POINTS, -(-rows // JOINT_TORQUE_SUPPORT_STRIDE))
        return domain.SUPPORT_POINTS

    def _residual_std_is_calibrated(self) -> bool:
        part = self.residual_
        return bool(getattr(part, "provides_std", False)
                    and getattr(part, "std_includes_noise", False))

    def _domain_inputs(self, Z):
        """The residual's input columns of Z (the leading blocks of [q, q̇, q̈])."""
        features = getattr(self.residual_, "features", "q")
        return Z[:, :check_feature_set(features) * self.n_joints_]

    def _cross_fit(self, residual, Z, target):
        """(distance to the other half's support (N,), target (N, k), the other half's
        prediction (N, k)) of every row: rows in `CROSS_FIT_BLOCKS` contiguous blocks, the
        residual fitted on the even ones and scored on the odd ones and the other way round
        (contiguous: neighbouring samples of a time series are nearly copies of each other).
        None when there are too few rows."""
        block = (np.arange(len(Z)) * self.CROSS_FIT_BLOCKS) // max(len(Z), 1) % 2 == 0
        predicted = np.empty_like(target)
        distance = np.empty(len(Z))
        inputs = self._domain_inputs(Z)
        for train in (block, ~block):
            if train.sum() < 2 or (~train).sum() < 1:
                return None
            part = clone(residual).fit(Z[train], target[train])
            predicted[~train] = np.asarray(part.predict(Z[~train])).reshape((~train).sum(), -1)
            distance[~train] = domain.distances(inputs[~train],
                                                domain.fit_support(
                                                    inputs[train],
                                                    self._support_points(int(train.sum()))))
        return distance, target, predicted

    def domain_distance(self, X) -> np.ndarray:
        """(N,) distance of each row's residual inputs to the training inputs, in training
        stds (0 on the data; the residual's weight is exp(−(d/ℓ)²))."""
        Z = self._validated_features(X)
        support = getattr(self, "domain_support_", None)
        if support is None:  # a model file from before the support was kept
            return np.zeros(len(Z))
        return domain.distances(self._domain_inputs(Z), support)

    def support_weight(self, X) -> np.ndarray:
        """(N,) the residual's weight w in [0, 1] at each row (1: where it has data)."""
        return domain.weight(self.domain_distance(X), self._length())

    def domain_terms(self, X, y, shared_growth: bool = False,
                     in_domain: str = "cross_fit") -> dict:
        """ℓ and g re-fitted on held-out readings `X`, `y` (contact-free, not trained on) that
        leave the training data — and come back to it: rows at many distances pin ℓ down
        (:func:`.domain.calibrate`; `shared_growth`: one growth for all axes in units of
        their σ²_far). `in_domain`: ``"cross_fit"`` keeps the fit's σ²_in (and c = 1);
        ``"held_out"`` fits σ²_in — at least the residual's error on its training rows
        (``residual_training_var_``), plus an excess — and the parameters' scale c on those
        rows too: a tighter std next to the data, see :func:`.domain.calibrate` for the trade.
        σ²_far stays the fit's. Changes nothing: returns the terms ``length`` (ℓ),
        ``in_var`` (σ²_in, k), ``growth`` (g, k), ``parameter_scale`` (c) and
        ``excess_var`` (σ²_in's excess over its floor, k), which
        :class:`~.domain_calibrated.DomainCalibratedHybrid` predicts with. A hybrid whose
        residual has a calibrated std of its own (a GP) has no support term to calibrate:
        ValueError."""
        check_is_fitted(self)
        if self._residual_std_is_calibrated() or getattr(self, "domain_support_", None) is None:
            raise ValueError("domain calibration: this hybrid's residual brings its own std "
                             "(or the model was saved before the support term); refit it "
                             "with a forest residual")
        Z = self._validated_features(X)
        Y = np.asarray(y, dtype=float).reshape(len(Z), -1)
        target = Y - self._physics(Z)
        predicted = np.asarray(self.residual_.predict(Z)).reshape(len(Z), -1)
        parameter_var = self.physics_._variance(self.physics_._select(Z), include_noise=False)
        floor = (self._training_var() if in_domain == "held_out"
                 else np.nan_to_num(self._noise_var()))
        length, in_var, growth, scale = domain.calibrate(
            domain.distances(self._domain_inputs(Z), self.domain_support_), target,
            predicted, floor, self.domain_far_var_, parameter_var, shared=shared_growth,
            in_domain=in_domain)
        return {"length": length, "in_var": in_var, "growth": growth,
                "parameter_scale": scale, "excess_var": in_var - floor}

    def _training_var(self):
        """The residual's error variance on its own training rows (k,); zeros for a model
        file from before it was kept."""
        var = getattr(self, "residual_training_var_", None)
        return np.zeros(self.n_outputs_) if var is None else np.asarray(var, dtype=float)

    def _length(self) -> float:
        return float(getattr(self, "domain_length_", np.inf))

    def _far_var(self):
        return np.asarray(getattr(self, "domain_far_var_", self._noise_var()), dtype=float)

    def _parameter_scale(self) -> float:
        """c, the calibrated scale of the physics parameters' variance (1 until calibrated)."""
        return float(getattr(self, "domain_parameter_scale_", 1.0))

    def _growth(self):
        return np.asarray(getattr(self, "domain_growth_", np.zeros(6)), dtype=float)

    def identified(self) -> dict:
        """The physics part's identified parameters (``physics_.identified()``)."""
        return self.physics_.identified()

    def summary(self) -> str:
        """The physics part's identified parameters, as lines a user reads."""
        return self.physics_.summary()

    def reading_to_model_frame(self):
        """The physics part's (the residual is learned in the reading's frame too)."""
        return self.physics_.reading_to_model_frame()

    def robot_description(self):
        """The physics part's robot (``physics_.robot_description()``)."""
        return self.physics_.robot_description()

    def payload_reading_map(self):
        """The physics part's (:meth:`~.base.Compensator.payload_reading_map`)."""
        return self.physics_.payload_reading_map()

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
        payload = self.physics_.packed_row(noise_var=np.zeros(6),
                                           factor_scale=np.sqrt(self._parameter_scale()))
        return CompiledHybrid(payload, residual.flat, self.n_joints_, self._domain_arrays())

    def _domain_arrays(self) -> tuple:
        """The support term's arrays in :func:`~..compiled.hybrid.hybrid_row`'s order."""
        support = getattr(self, "domain_support_", None)
        d = self._domain_inputs(np.zeros((1, 3 * self.n_joints_))).shape[1]
        if support is None:
            support = {"points": np.zeros((0, d)), "nodes": np.zeros((0, 5), np.int64),
                       "splits": np.zeros(0), "center": np.zeros(d), "scale": np.ones(d)}
        var = np.vstack([np.nan_to_num(self._noise_var()), np.nan_to_num(self._far_var()),
                         self._growth() ** 2])
        return (support["points"], support["nodes"], support["splits"], support["center"],
                support["scale"], var, np.array([self._length()]))

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
        in_var, far_var = np.nan_to_num(self._noise_var()), np.nan_to_num(self._far_var())
        growth2, scale = self._growth() ** 2, self._parameter_scale()

        def predict(row):
            mean, physics_std = physics(row)
            internal, residual_std = residual(row)
            if calibrated:
                return mean + internal, np.sqrt(physics_std ** 2 + residual_std ** 2)
            d = self.domain_distance(row[None, :])[0]
            w = domain.weight(d, self._length())
            var = scale * physics_std ** 2 + w * in_var + (1 - w) * far_var + growth2 * d
            return mean + w * internal, np.sqrt(var)

        return predict

    def in_domain_std(self) -> np.ndarray:
        """The hybrid's RMS error on its own training rows, per axis (k,): what the trust
        analysis compares the predictive std with, as it does a physics model's
        ``residual_rms_`` (:mod:`~ftdrake.compensation.evaluation.trust`). σ_in for a model
        file from before that error was kept."""
        check_is_fitted(self)
        var = getattr(self, "residual_training_var_", None)
        return np.sqrt(self._noise_var() if var is None else np.asarray(var, dtype=float))

    def _noise_var(self):
        var = getattr(self, "residual_noise_var_", None)
        if var is None:  # a model file from before the hybrid had a std: the physics part's
            var = np.asarray(self.physics_.residual_rms_) ** 2
        return np.asarray(var, dtype=float)

    def _physics(self, Z):
        return np.asarray(self.physics_.predict(Z)).reshape(len(Z), -1)

    def _support(self, Z):
        """(w, d), each (N, 1): the residual's support weight and distance at rows Z (1 and
        0 with a calibrated residual std or without a support)."""
        support = getattr(self, "domain_support_", None)
        if self._residual_std_is_calibrated() or support is None:
            return np.ones((len(Z), 1)), np.zeros((len(Z), 1))
        d = domain.distances(self._domain_inputs(Z), support)
        return domain.weight(d, self._length())[:, None], d[:, None]

    def _predict(self, Z):
        residual = np.asarray(self.residual_.predict(Z)).reshape(len(Z), -1)
        return self._physics(Z) + self._support(Z)[0] * residual

    def _predict_std(self, Z):
        var = self._parameter_scale() * self.physics_._variance(self.physics_._select(Z),
                                                                include_noise=False)
        if self._residual_std_is_calibrated():
            var = var + np.asarray(self.residual_.predict_std(Z)).reshape(len(Z), -1) ** 2
        else:
            w, d = self._support(Z)
            var = (var + w * np.nan_to_num(self._noise_var())
                   + (1 - w) * np.nan_to_num(self._far_var()) + self._growth() ** 2 * d)
        return np.sqrt(var)


def default_residual() -> RandomForestCompensator:
    """The residual a hybrid gets by default: one multi-output forest of 50 trees on ``q``,
    at least 40 training rows in a leaf.

    Why not the study's per-axis forests: the residual is small and smooth (cable, cross-talk,
    what the rigid model misses), one forest predicts all six axes of it, and the hybrid must
    run in the loop, where one multi-output forest of 50 trees costs a fraction of six
    per-axis forests of 100 (``benchmarks/compensator_latency.py`` measures both).

    Why 40 rows a leaf: a smooth residual needs no finer leaves, and the file is a quarter of
    the nodes (``benchmarks/model_size.py`` measures it; the figures: docs, Derivations). The
    size grows with the training rows (training's ``max_rows`` bounds it).
    """
    return RandomForestCompensator(features="q", per_output=False, n_estimators=50,
                                   min_samples_leaf=40, random_state=0)


#: The most training rows a joint-torque hybrid's support keeps (``support_points=None``),
#: and the least stride between them: its residual's inputs are q, q̇, q̈, three times a
#: wrench residual's q, so that a support of every third row holds no more numbers than the
#: wrench's of every row; at 100–1000 Hz neighbouring rows are near copies.
JOINT_TORQUE_SUPPORT_POINTS = 1000
JOINT_TORQUE_SUPPORT_STRIDE = 3


def joint_torque_residual() -> RandomForestCompensator:
    """The residual a hybrid on joint torques gets by default (physics: the arm's model,
    :class:`~.arm.ArmDynamicsCompensator`): one multi-output forest of 25 trees on
    ``q, q̇, q̈``, at least 20 training rows in a leaf.

    Why not :func:`default_residual` (a forest on ``q``): what the arm's rigid-body model
    and its friction terms miss in joint torques depends on the motion (friction that is not
    viscous plus Coulomb, its dependence on load and position, the drives' dynamics), which a
    function of ``q`` alone cannot hold. Its size: 25 trees of 20 rows a leaf have as many
    nodes as the wrench residual's 50 of 40, and the support (:data:`JOINT_TORQUE_SUPPORT_POINTS`,
    :data:`JOINT_TORQUE_SUPPORT_STRIDE`) holds no more numbers than the wrench's, so the model
    file is no larger than with :func:`default_residual` on the same data.
    ``benchmarks/joint_torque_residual.py`` measures the accuracy and the size, and how the
    leaf size and trees were chosen (``docs/results/torque-models.md``).
    """
    return RandomForestCompensator(features="q,qd,qdd", per_output=False, n_estimators=25,
                                   min_samples_leaf=20, random_state=0)
