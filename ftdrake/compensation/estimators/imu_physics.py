"""The physics payload model with an IMU at the sensor: the tool's inertial wrench from the
measured acceleration and angular rate instead of the joints' derivatives.

:class:`~ftdrake.compensation.estimators.physics.PhysicsPayloadCompensator` computes ω, α and
``a − g`` of the sensor frame S from ``(q, q̇, q̈)`` through the robot's kinematics: what the
joint encoders see. Where the arm between the encoders and the tool bends (gearbox springs, a
flexible link), the tool vibrates with motion the encoders miss, and so does the model. An
IMU at the sensor measures the tool's motion itself:

* ``a − g`` = the accelerometer's reading ``f_S`` (proper acceleration of So in S, m/s²; the
  convention of Drake's ``Accelerometer``, :mod:`ftdrake.systems.imu`),
* ω = the gyroscope's reading ``ω_S`` (rad/s, in S),
* α = the derivative of ω (rad/s², in S), given as a column as ``q̈`` is: the causal,
  filtered derivative of the gyroscope (:func:`ftdrake.signals.causal_acceleration`; the
  simulation's ``imu_alpha_*`` columns).

The regressor, the identification and the predictive std are the physics model's (same
parameters θ = [m, m·c, I_So, biases]); only the kinematics come from the IMU. The IMU must
sit at So with its axes along S (as the simulated one does); gravity in S is then inside
``f_S``, and q is used only where a weight carried without inertia or a tether needs the
pose.

Input layout: ``X = [q, q̇, q̈, f_S (3), ω_S (3), α_S (3)]``, N × (3n + 9), the IMU columns in
the order of :data:`ftdrake.conventions.IMU_INPUTS`. No temperature column (refused), mode
"dynamic" only. The row path goes through ``predict`` (no compiled kernel and no fused loop
update). In the runtime chain the ``imu`` input (``[f_S, ω_S]``) feeds the IMU columns, α
derived there from ω (:class:`~ftdrake.runtime.compensator.CompensatorSystem`).
"""

from __future__ import annotations

import numpy as np

from ...errors import ConfigError
from ..identification.payload_identification import payload_regressor
from .base import generic_row_predictor
from .physics import PhysicsPayloadCompensator

#: Columns the IMU adds after the 3n joint columns: f_S, ω_S, α_S.
IMU_WIDTH = 9


class ImuPayloadCompensator(PhysicsPayloadCompensator):
    """Rigid-payload model of the internal wrench with the sensor's motion from an IMU.

    Parameters: those of :class:`~ftdrake.compensation.estimators.physics.
    PhysicsPayloadCompensator` (``mode`` must be ``"dynamic"``, ``features``
    ``"q,qd,qdd"``).

    X: ``[q, q̇, q̈, f_S, ω_S, α_S]`` (N × (3n + 9)): joint positions (rad), velocities (rad/s),
    accelerations (rad/s², unused but kept for the layout and the training range), the
    accelerometer's proper acceleration of So in S (m/s², +9.81 up at rest), the gyroscope's
    ω of S in S (rad/s) and α of S in S (rad/s²). Fitted attributes: the physics model's.
    """

    #: Its X carries an IMU's nine columns (the chain's ``imu`` input feeds them).
    needs_imu = True

    def fit(self, X, y, *, wrench_delay_s: float | None = None):
        """Fits on rows `X` (N, 3n + 9) ``[q, q̇, q̈, f_S, ω_S, α_S]`` and wrench targets `y`
        (N, 6); see the physics model's ``fit``."""
        self._validate_params()  # a bad parameter is named before the layout is checked
        shape = np.shape(X)
        if len(shape) != 2 or shape[1] < 3 + IMU_WIDTH or (shape[1] - IMU_WIDTH) % 3:
            raise ValueError(
                f"{type(self).__name__} takes X = [q, qd, qdd, imu_acc (3), imu_gyro (3), "
                f"imu_alpha (3)]: 3n + 9 columns; got shape {shape} (a temperature column is "
                "not supported with the IMU)")
        joints = self._kinematics().num_joints
        if shape[1] != 3 * joints + IMU_WIDTH:
            raise ValueError(
                f"X has {shape[1]} columns; the robot's {joints} joints and the IMU take "
                f"{3 * joints + IMU_WIDTH}: [q, qd, qdd] ({3 * joints}) and imu_acc (3), "
                "imu_gyro (3), imu_alpha (3)")
        if self.mode != "dynamic":
            raise ConfigError("mode: the IMU model is 'dynamic' (it exists for the motion "
                              "terms); use PhysicsPayloadCompensator(mode='static') without "
                              "an IMU")
        return super().fit(X, y, wrench_delay_s=wrench_delay_s)

    def _fit(self, Z, Y):
        # The base class counts joints as if every column were one: 3n + 9 columns are n.
        self.n_joints_ = (self.n_features_in_ - IMU_WIDTH) // 3
        super()._fit(Z, Y)

    def _select(self, X) -> np.ndarray:
        """All columns: [q, q̇, q̈] (the feature set is "q,qd,qdd") and the IMU's nine."""
        width = 3 * ((self.n_features_in_ - IMU_WIDTH) // 3) + IMU_WIDTH
        return np.asarray(X[:, :width], dtype=float)

    def regressor(self, X) -> np.ndarray:
        """The (N, 6, p) regressor from the IMU columns of full rows X (3n + 9): the physics
        model's, with ω = ω_S, α = α_S and a − g = f_S (see the module docstring)."""
        X = np.asarray(X, dtype=float)
        n = (X.shape[1] - IMU_WIDTH) // 3
        imu = X[:, 3 * n:3 * n + IMU_WIDTH]
        gravity_S = None
        if self.weight_without_inertia:  # the pose only orients gravity
            gravity_S = self._kinematics().evaluate(
                X[:, :n], X[:, n:2 * n], X[:, 2 * n:3 * n]).g_S
        A = payload_regressor(imu[:, 3:6], imu[:, 6:9], imu[:, 0:3], gravity_S)
        if getattr(self, "tether_frame_", None) is None:
            return A
        return np.concatenate([A, self._tether_columns(X)], axis=2)

    # -- the row path: through predict (no compiled kernel takes the IMU) -------------------
    def predict_row(self, x) -> np.ndarray:
        """One row (3n + 9,) → wrench (6,)."""
        return self.row_predictor()(np.asarray(x, dtype=float))[0]

    def row_predictor(self, include_noise: bool = True):
        """``row (3n + 9,) → (wrench, std)`` through ``predict`` and ``predict_std``."""
        if not include_noise:
            raise ConfigError("the IMU model's row path gives the std with noise only")
        return generic_row_predictor(self)

    def fused_loop_update(self):
        """None: the compiled loop update computes the kinematics from joints only."""

    def packed_row(self, *_args, **_kwargs):
        """Refused: the compiled payload kernel computes the kinematics from joints only."""
        raise TypeError(f"{type(self).__name__} has no compiled row kernel (its kinematics "
                        "come from the IMU columns)")
