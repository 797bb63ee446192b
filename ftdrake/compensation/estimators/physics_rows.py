"""The physics payload model's compiled row path, a mixin of
:class:`~ftdrake.compensation.estimators.physics.PhysicsPayloadCompensator`: one row
``[q, q̇, q̈]`` (3n) → the internal wrench (6, in S; N, N·m) and its std in one numba kernel
(:mod:`ftdrake.compensation.compiled.payload`: the serial chain's kinematics, the regressor
row, the mean ``B·θ`` and the std), and the fused loop update a control loop runs per sample
(:func:`~ftdrake.compensation.compiled.loop.compensate_with_payload`: the input checks, the
q̈ estimate, the prediction and the compensated wrench in one call).

Each reads the fitted model's attributes (its chain, gravity, mounting, parameters,
covariance factor, tether and temperature terms) when it is made: refitting the model
afterwards does not change a predictor or update already made.
"""

from __future__ import annotations

import weakref

import numpy as np
from sklearn.utils.validation import check_is_fitted

from ...physics.robot import fixed_joint_values
from ..compiled.loop import compensate_with_payload
from ..compiled.payload import pack_payload_row, payload_mean_std, payload_predict

#: Row-kernel arguments per model (weak: a model's cache goes with it, never into its file).
_ROW_ARGS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class PayloadRowKernels:
    """The compiled row path of a fitted physics payload model (module docstring)."""

    def predict_row(self, x) -> np.ndarray:
        """One full-layout row (3n,) → wrench (6,), without input validation (control loops):
        one compiled kernel (kinematics, regressor row, product with the parameters)."""
        x = np.asarray(x, dtype=float)
        if getattr(self, "temperature_in_", False) or not np.array_equal(
                self.reading_matrix(), np.eye(6)) or len(self.parameters_) == 22:
            return self.row_predictor()(x)[0]
        out = np.empty(6)
        payload_predict(x, *self._row_kernel_args(), self.parameters_, out)
        return out

    def fused_loop_update(self):
        """The compiled payload model's loop update
        (:func:`~ftdrake.compensation.compiled.loop.compensate_with_payload`) and its arrays
        (the current parameters and covariance factor, as :meth:`row_predictor` binds them);
        None for a model trained with the temperature (its row predictor adds that term)."""
        check_is_fitted(self)
        if getattr(self, "temperature_in_", False):
            return None
        return compensate_with_payload, self.packed_row()

    def row_predictor(self, include_noise: bool = True):
        """``row → (wrench, std)``: one compiled kernel with this model's chain, current
        parameters and covariance factor bound (refitting the model afterwards does not
        change it): kinematics, regressor row, mean ``B·θ`` and std (see the class
        docstring), mounting rotation included; the temperature term (row's last entry) is
        added after it. ``include_noise=False``: the parameters' uncertainty only."""
        reals, ints = self.packed_row(None if include_noise else np.zeros(6))
        reference = getattr(self, "temperature_reference_", None)
        if not (getattr(self, "temperature_in_", False) and reference is not None):
            def predict(row):
                mean, std = np.empty(6), np.empty(6)
                payload_mean_std(row, reals, ints, mean, std)
                return mean, std

            return predict
        k = np.asarray(getattr(self, "temperature_coefficients_", np.zeros(6)), dtype=float)
        k_se = np.nan_to_num(np.asarray(getattr(self, "temperature_std_errors_", np.zeros(6)),
                                        dtype=float))

        def predict_with_temperature(row):
            mean, std = np.empty(6), np.empty(6)
            payload_mean_std(row, reals, ints, mean, std)
            dt = row[-1] - reference
            mean += k * dt
            std[:] = np.sqrt(std * std + (k_se * dt) ** 2)
            return mean, std

        return predict_with_temperature

    def packed_row(self, noise_var=None, factor_scale: float = 1.0
                   ) -> tuple[np.ndarray, np.ndarray]:
        """This model's row kernel data, packed for
        :func:`~ftdrake.compensation.compiled.payload.payload_mean_var` (a copy: refitting
        the model afterwards does not change it): the chain, gravity, the mounting rotation,
        the current parameters, the covariance factor and the variance σ² added per axis
        (default: the residual RMS², the model's own noise term); `factor_scale` multiplies the
        covariance factor (a hybrid's calibrated scale of the parameters' std). No
        temperature term."""
        n, gravity, X_pre, kinds, axes, q_index, v_index, static = self._row_kernel_args()
        factor, own_noise_var, block_T = self._std_terms()
        tether = None
        if getattr(self, "tether_frame_", None) is not None:
            tether = (self.tether_frame_names().index(self.tether_frame_),
                      self.tether_anchor_, self.tether_attach_)
        return pack_payload_row((X_pre, kinds, axes, q_index, v_index), n, gravity, static,
                                block_T, self.parameters_, factor * factor_scale,
                                own_noise_var if noise_var is None else noise_var, tether)

    def _row_kernel_args(self) -> tuple:
        # Looking the chain up through the robot description costs microseconds (building and
        # hashing the description); the row path remembers it per model and per parameters.
        key = (self.robot, getattr(self, "robot_model_", None), self.sensor_frame,
               self.base_frame, tuple(self.gravity), tuple(self.package_xmls), self.mode,
               self._joint_columns(), fixed_joint_values(self.fixed_joints))
        cached = _ROW_ARGS.get(self)
        if cached is None or cached[0] != key:
            kin = self._kinematics()
            cached = (key, (kin.n_joints, kin.gravity, *kin.chain.kernel_args(),
                            self.mode == "static"))
            _ROW_ARGS[self] = cached
        return cached[1]
