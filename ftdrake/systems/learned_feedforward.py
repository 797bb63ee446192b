"""LearnedFeedforward: a GP-learned joint-torque correction added to the controller's output.

The seed paper's torque compensation (its §2): the controller's feedforward comes from an
imperfect model (here: the tool 15 % too light with its centre of mass off, and joint
friction the model does not know); the torque the feedback had to supply in earlier
executions is learned as a function of the *desired* state ``x_d = [q_d, q̇_d, q̈_d]`` by one
Gaussian process per joint, and fed forward in the next execution. Indexed by state, not by
time, the correction carries over to another trajectory through the same region; the GP's
std says where it does not (§2.1: "GPR still gives an estimate, however, with a wide
confidence interval").

Learning target (iteration k, per joint, at the log's samples): ``y = c_k + τ_fb,k``, the
correction applied in that run plus what the feedback added on top of it,
``τ_fb = M̂(q) (kp (q_d − q) + kd (q̇_d − q̇))`` with the controller's own model M̂. When the
correction is right, τ_fb → 0 and y stops changing.

Data subset (the paper's "selecting data subsets for more efficient learning"): the GP keeps
``max_points`` rows chosen by greedy farthest-point selection in the standardised input
space (:func:`ftdrake.compensation.estimators.gpr.farthest_point_subset`): each new row is the one
farthest from those already kept — for an RBF kernel, a stand-in for "the row with the
largest predictive variance" — so the subset covers the trajectory evenly instead of piling
up where the arm moved slowly. Hyperparameters (ARD length scales, signal and noise
variance per joint) maximise the marginal likelihood on a random sample of the rows.

Confidence rule (how the correction is scaled down where the GP does not know): per joint,
with σ the GP's std of the *function* (observation noise excluded) and σ₀ its prior std
(what σ tends to far from every training row),
``confidence = clip((reject_ratio − σ/σ₀) / (reject_ratio − trust_ratio), 0, 1)`` and the
applied correction is ``confidence · mean``. Defaults: full correction while σ ≤ 0.5 σ₀,
none once σ ≥ 0.9 σ₀ (the query is then as uncertain as if there were no data), linear in
between. Far from the data the GP's mean returns to the training mean, not to zero; the rule
zeroes it there. The first time a joint's confidence reaches 0 in a run, the system logs a
warning naming the joint, the time and σ/σ₀.
"""

from __future__ import annotations

import logging

import numpy as np
from numba import njit
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem, ValueProducer

from ..compensation.compiled.gp import CompiledGaussianProcess, _gp_predict_one
from ..compensation.estimators.gpr import GPRCompensator
from ..errors import FtdrakeError

logger = logging.getLogger(__name__)

#: Fewest rows a feedforward GP is fitted on (0.2 s at 1 kHz): fewer cannot separate a
#: function of the state from noise, and the subset would be the whole (tiny) data set.
MIN_SAMPLES = 200


class FeedforwardDataError(FtdrakeError, ValueError):
    """The data given to learn a feedforward cannot be used (too few rows, bad shapes)."""


def fit_feedforward_gp(X, tau, *, max_points: int = 200, optimize_points: int = 300,
                       random_state=0) -> GPRCompensator:
    """Fits one GP per joint: desired ``X = [q_d, q̇_d, q̈_d]`` (N × 3n) → torque (N × n).

    `tau` is the torque the feedback had to supply (N·m; see the module docstring). The GP
    keeps `max_points` rows (farthest-point subset); its std excludes the observation noise
    (``include_noise=False``), so it measures how well the data cover a query.
    Raises FeedforwardDataError for fewer than MIN_SAMPLES rows, mismatched shapes or
    non-finite values.
    """
    X = np.asarray(X, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if X.ndim != 2 or tau.ndim != 2 or X.shape[1] != 3 * tau.shape[1]:
        raise FeedforwardDataError(
            f"need X (N × 3n: q_d, q̇_d, q̈_d) and torques (N × n); got {X.shape} and "
            f"{tau.shape}")
    if len(X) != len(tau):
        raise FeedforwardDataError(f"X has {len(X)} rows but the torques {len(tau)}")
    if len(X) < MIN_SAMPLES:
        raise FeedforwardDataError(
            f"{len(X)} samples are too few to learn a feedforward (need >= {MIN_SAMPLES}, "
            "0.2 s at 1 kHz); run a longer trajectory")
    for a, name in ((X, "desired state"), (tau, "torque")):
        if not np.isfinite(a).all():
            raise FeedforwardDataError(f"the {name} holds NaN or infinity; the run diverged?")
    model = GPRCompensator(features="q,qd,qdd", max_points=max_points, subset="greedy",
                           optimize_points=optimize_points, include_noise=False,
                           random_state=random_state)
    return model.fit(X, tau)


class LearnedFeedforward(LeafSystem):
    """Adds a GP's torque correction, scaled by its confidence, to the controller's output.

    Input ports:
      control (n): the controller's joint torques (N·m).
      desired_state (2n): ``[q_d (rad), q̇_d (rad/s)]`` of the trajectory.
      desired_acceleration (n): ``q̈_d`` (rad/s²).
    Output ports:
      control (n): control + correction (N·m), to the plant's actuation (or friction) input.
      correction (n): ``confidence · mean``, the torque added (N·m).
      correction_std (n): the GP's std σ of the correction's mean (N·m; noise excluded).
      confidence (n): the factor in [0, 1] applied to the mean (module docstring's rule).
      status (3n): ``[correction, correction_std, confidence]`` (for one logger).
    State: none. The GP is evaluated once per change of the desired inputs (a cache entry
    every output reads), by compiled code (``CompiledGaussianProcess``).

    `model` is a GPRCompensator fitted by :func:`fit_feedforward_gp` (inputs ``q,qd,qdd``,
    n outputs); `n_joints`, if given, must match it.
    """

    def __init__(self, model, *, n_joints: int | None = None, trust_ratio: float = 0.5,
                 reject_ratio: float = 0.9):
        super().__init__()
        check_feedforward_model(model, n_joints)
        if not 0 <= trust_ratio < reject_ratio <= 1:
            raise ValueError(f"need 0 <= trust_ratio < reject_ratio <= 1; got {trust_ratio}, "
                             f"{reject_ratio}")
        self.model = model
        self.trust_ratio, self.reject_ratio = float(trust_ratio), float(reject_ratio)
        n = self.n = int(model.n_joints_)
        self._gp = CompiledGaussianProcess(model)
        self.prior_std = prior_std(model)
        self._rule = np.array([self.trust_ratio, self.reject_ratio])
        self._x = np.empty(3 * n)
        self._mean, self._std = np.empty(n), np.empty(n)
        self._warned: set[int] = set()
        self.evaluate_one(np.zeros(3 * n))  # compiles (or loads from numba's cache) now

        self._control = self.DeclareVectorInputPort("control", n)
        self._desired = self.DeclareVectorInputPort("desired_state", 2 * n)
        self._acceleration = self.DeclareVectorInputPort("desired_acceleration", n)
        desired = {self.input_port_ticket(p.get_index())
                   for p in (self._desired, self._acceleration)}
        self._cache = self.DeclareCacheEntry(
            "status", ValueProducer(allocate=AbstractValue.Make(np.zeros(3 * n)).Clone,
                                    calc=self._calc_status), desired)
        status = {self._cache.ticket()}
        self.DeclareVectorOutputPort(
            "control", n, self._calc_control,
            prerequisites_of_calc=status | {self.input_port_ticket(self._control.get_index())})
        for name, block in (("correction", 0), ("correction_std", 1), ("confidence", 2)):
            self.DeclareVectorOutputPort(name, n, self._block_calc(block),
                                         prerequisites_of_calc=status)
        self.DeclareVectorOutputPort("status", 3 * n, self._calc_status_port,
                                     prerequisites_of_calc=status)

    # -- ports ------------------------------------------------------------------------------
    def get_input_port_control(self):
        return self.GetInputPort("control")

    def get_input_port_desired_state(self):
        return self.GetInputPort("desired_state")

    def get_input_port_desired_acceleration(self):
        return self.GetInputPort("desired_acceleration")

    def get_output_port_control(self):
        return self.GetOutputPort("control")

    def get_output_port_correction(self):
        return self.GetOutputPort("correction")

    def get_output_port_correction_std(self):
        return self.GetOutputPort("correction_std")

    def get_output_port_confidence(self):
        return self.GetOutputPort("confidence")

    def get_output_port_status(self):
        return self.GetOutputPort("status")

    # -- the rule, for one row and for many -----------------------------------------------
    def evaluate_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x (3n,) = [q_d, q̇_d, q̈_d] → ``[correction, std, confidence]`` (3n,)."""
        out = np.empty(3 * self.n) if out is None else out
        # One compiled call: the GP's mean and std and the confidence rule (no Python checks;
        # a non-finite x gives no correction and confidence 0).
        _feedforward_one(np.asarray(x, dtype=float), *self._gp._arrays, self.prior_std,
                         self._rule, self._mean, self._std, out)
        return out

    def evaluate(self, X) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """X (N, 3n) → (correction, std, confidence), each (N, n); as the loop computes them."""
        mean, std = self._gp.predict_with_std(X)
        confidence = self._confidence(std)
        return confidence * mean, std, confidence

    def _confidence(self, std: np.ndarray) -> np.ndarray:
        ratio = std / self.prior_std
        return np.clip((self.reject_ratio - ratio) / (self.reject_ratio - self.trust_ratio),
                       0.0, 1.0)

    # -- calcs ------------------------------------------------------------------------------
    def _calc_status(self, context, value):
        n = self.n
        x = self._x
        x[:2 * n] = self._desired.Eval(context)
        x[2 * n:] = self._acceleration.Eval(context)
        status = value.get_mutable_value()
        _feedforward_one(x, *self._gp._arrays, self.prior_std, self._rule, self._mean,
                         self._std, status)
        if status[2 * n:].min() <= 0.0:
            self._warn_unknown(context.get_time(), status)

    def _warn_unknown(self, t: float, status: np.ndarray) -> None:
        n = self.n
        for j in np.flatnonzero(status[2 * n:] <= 0.0):
            if j not in self._warned:
                self._warned.add(int(j))
                logger.warning(
                    "learned feedforward: joint %d's correction scaled to zero from t = %.3f s: "
                    "the desired state is outside the data it was learned from "
                    "(σ/σ₀ = %.2f >= reject_ratio %.2f)", j, t,
                    status[n + j] / self.prior_std[j], self.reject_ratio)

    def _status(self, context) -> np.ndarray:
        return self._cache.Eval(context)

    def _calc_control(self, context, output: BasicVector):
        output.SetFromVector(self._control.Eval(context) + self._status(context)[:self.n])

    def _block_calc(self, block: int):
        n = self.n

        def calc(context, output: BasicVector):
            output.SetFromVector(self._status(context)[block * n:(block + 1) * n])

        return calc

    def _calc_status_port(self, context, output: BasicVector):
        output.SetFromVector(self._status(context))


@njit(cache=True)
def _feedforward_one(x, input_mean, input_scale, points_T, inv_length, signal, noise, L,
                     alpha_T, kernel_of_output, target_mean, target_scale, prior, rule, mean,
                     std, out):
    n = len(mean)
    for i in range(len(x)):
        if not np.isfinite(x[i]):
            out[:] = 0.0
            out[n:2 * n] = np.inf
            return
    _gp_predict_one(x, input_mean, input_scale, points_T, inv_length, signal, noise, L,
                    alpha_T, kernel_of_output, target_mean, target_scale, mean, std)
    trust, reject = rule[0], rule[1]
    for j in range(n):
        c = min(max((reject - std[j] / prior[j]) / (reject - trust), 0.0), 1.0)
        out[j] = c * mean[j]
        out[n + j] = std[j]
        out[2 * n + j] = c


def prior_std(model: GPRCompensator) -> np.ndarray:
    """Per output, the std the GP's function tends to far from the data (N·m): √s · scale."""
    groups = model.output_groups()
    s = np.empty(model.n_outputs_)
    for g, cols in enumerate(groups):
        s[cols] = model.signal_variance_[g]
    return np.sqrt(s) * model.target_scale_


def check_feedforward_model(model, n_joints: int | None = None) -> None:
    """Raises FeedforwardDataError unless `model` is a fitted feedforward GP for n joints."""
    if not isinstance(model, GPRCompensator) or not hasattr(model, "L_"):
        raise FeedforwardDataError(
            f"a learned feedforward needs a fitted GPRCompensator; got {type(model).__name__}")
    if model.features != "q,qd,qdd":
        raise FeedforwardDataError(
            f"a feedforward GP uses q, q̇ and q̈ (features 'q,qd,qdd'); got {model.features!r}")
    if model.n_outputs_ != model.n_joints_:
        raise FeedforwardDataError(
            f"a feedforward GP has one output per joint ({model.n_joints_}); got "
            f"{model.n_outputs_}")
    if n_joints is not None and int(n_joints) != model.n_joints_:
        raise FeedforwardDataError(
            f"the model was learned for {model.n_joints_} joints; the arm has {n_joints}")
