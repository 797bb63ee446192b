"""The static payload model of a sensor whose orientation a table gives directly (no robot).

``ftdrake calibrate`` on a table with an orientation per pose (quaternion ``qw, qx, qy, qz``,
rotation matrix ``r00..r22``, ``roll, pitch, yaw`` or gravity ``gx, gy, gz``;
:data:`~.static_table.ORIENTATIONS`) identifies mass, first moment and biases without a robot
description. :class:`OrientationPayloadCompensator` is that calibration as a compensator, so
that it is saved as a model file that ``evaluate``, ``replay`` and ``serve`` load: its
"joints" are the orientation columns (``n_joints_`` = 4, 9, 3 or 3; q̇ and q̈ unused, zero
in a table of static poses), and it predicts the reading (N, N·m, in the frame the sensor
measures in)::

    reading = A(g_S)·[m, m·c, b]            (gravity + bias)
    reading = M·[m·g_S; m·c × g_S] + b      (with a gain/cross-talk correction, M = C⁻¹)

plus ``k·(T − T_ref)`` with a temperature column (°C, X's last column). ``g_S`` (m/s²) is
gravity in S from the orientation columns (:func:`~.static_table.gravity_in_sensor`).
``predict_std``: the std of a new reading, ``sqrt(diag(A Σ Aᵀ) + σ²)`` with Σ the static
parameters' covariance (gravity + bias; a correction's model keeps σ² only) and σ the
per-axis residual RMS of the calibration.

A replay log or live stream feeds the orientation columns as ``q_0..q_{k-1}`` (in the order
of :data:`~.static_table.ORIENTATIONS`) with ``qd_*`` zero.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pandas as pd
from sklearn.utils._param_validation import StrOptions

from ...conventions import GRAVITY_W
from ...errors import ConfigError
from ..estimators.base import Compensator
from ..identification.consistent import identify_consistent
from ..identification.payload_identification import payload_regressor, project_out
from .static_table import ORIENTATIONS, gravity_in_sensor

#: The static parameters' columns of the payload regressor: m, m·c, biases.
STATIC_COLUMNS = [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]


class OrientationPayloadCompensator(Compensator):
    """Gravity + bias (and optionally a gain/cross-talk correction) of a static calibration
    whose orientation is given as table columns; see the module docstring.

    Parameters
    ----------
    features : "q" (the orientation columns; a static model uses nothing else).
    orientation : a key of :data:`~.static_table.ORIENTATIONS`.
    gravity : gravity in the world frame, m/s².

    Fitted attributes (set by :meth:`from_calibration`, or by ``fit`` through a static
    calibration of its rows): ``parameters_`` (10: m kg, m·c kg·m, biases N and N·m),
    ``covariance_`` (10 × 10), ``residual_rms_`` (6), ``sensor_matrix_`` (6 × 6 or None),
    ``correction_bias_`` (6), ``correction_payload_`` ([m, m·c]), ``temperature_reference_``
    (°C or None), ``temperature_coefficients_`` (6, per K).
    """

    provides_std = True
    std_includes_noise = True

    _parameter_constraints: ClassVar[dict] = {
        **Compensator._parameter_constraints,
        "orientation": [StrOptions(set(ORIENTATIONS))],
        "gravity": ["array-like"],
    }

    def __init__(self, features="q", orientation="quaternion", gravity=GRAVITY_W):
        super().__init__(features=features)
        self.orientation = orientation
        self.gravity = gravity

    @classmethod
    def from_calibration(cls, cal, X, Y) -> OrientationPayloadCompensator:
        """The compensator of a :class:`~.calibration.StaticCalibration` `cal` identified
        from orientation columns, with `X` (N × 3k ``[o, 0, 0]`` [, T]) and `Y` (N × 6) the
        rows it was identified from (for the training ranges)."""
        model = cls(orientation=cal.source, gravity=tuple(cal.gravity))
        model._set_layout(np.asarray(X, float), np.asarray(Y, float))
        model._take(cal)
        return model

    def _set_layout(self, X, Y):
        self.n_features_in_ = X.shape[1]
        self.temperature_in_ = bool(X.shape[1] % 3 == 1)
        self.n_joints_ = (X.shape[1] - self.temperature_in_) // 3
        self.n_outputs_ = Y.shape[1]
        self._y_was_1d = False
        self.input_min_, self.input_max_ = X.min(axis=0), X.max(axis=0)

    def _take(self, cal):
        self.parameters_ = np.asarray(cal.parameters, float)
        self.covariance_ = np.nan_to_num(np.asarray(cal.covariance, float))
        self.residual_rms_ = np.asarray(cal.residual_rms, float)
        self.temperature_reference_ = cal.temperature_reference
        self.temperature_coefficients_ = (np.zeros(6) if cal.temperature_coefficients is None
                                          else np.asarray(cal.temperature_coefficients, float))
        self.sensor_matrix_ = None
        self.correction_bias_ = np.zeros(6)
        self.correction_payload_ = self.parameters_[:4].copy()
        corr = cal.correction
        if corr is not None and corr.payload is not None:
            self.sensor_matrix_ = np.asarray(corr.sensor_matrix, float)
            self.correction_bias_ = np.asarray(corr.bias, float)
            self.correction_payload_ = np.asarray(corr.payload, float)
            self.residual_rms_ = np.asarray(corr.residual_rms, float)
            if corr.temperature_coefficients is not None:
                self.temperature_coefficients_ = np.asarray(corr.temperature_coefficients,
                                                            float)

    # -- the compensator --------------------------------------------------------------------
    def _fit(self, Z, Y):
        """The static calibration of these rows (consistent: mass > 0), as ``calibrate``'s
        (no correction; a temperature column adds the per-axis drift)."""
        A = self._regressor(self.gravity_in_sensor(Z))
        d = None
        self.temperature_reference_ = None
        self.temperature_coefficients_ = np.zeros(6)
        if self.temperature_in_:
            self.temperature_reference_ = float(np.mean(Z[:, -1]))
            d = Z[:, -1] - self.temperature_reference_
            d = d if np.any(np.abs(d) > 1e-9) else None
        A_fit, Y_fit = (A, Y) if d is None else (project_out(A, d), project_out(Y, d))
        result = identify_consistent(A_fit, Y_fit, static=True)
        self.parameters_ = result.theta[STATIC_COLUMNS]
        self.covariance_ = np.nan_to_num(result.covariance[np.ix_(STATIC_COLUMNS,
                                                                  STATIC_COLUMNS)])
        residual = Y - A @ self.parameters_
        if d is not None:
            self.temperature_coefficients_ = residual.T @ d / (d @ d)
            residual = residual - np.outer(d, self.temperature_coefficients_)
        self.residual_rms_ = np.sqrt(np.mean(residual ** 2, axis=0))
        self.sensor_matrix_ = None
        self.correction_bias_ = np.zeros(6)
        self.correction_payload_ = self.parameters_[:4].copy()

    def _frame(self, Z) -> pd.DataFrame:
        names = ORIENTATIONS.get(self.orientation)
        if names is None:
            raise ConfigError(f"orientation must be one of {list(ORIENTATIONS)}, got "
                              f"{self.orientation!r}")
        if Z.shape[1] - self.temperature_in_ != len(names):
            raise ValueError(f"the {self.orientation} model takes {len(names)} orientation "
                             f"columns {list(names)}; got {Z.shape[1]}")
        return pd.DataFrame(dict(zip(names, Z[:, :len(names)].T, strict=True)))

    def gravity_in_sensor(self, Z) -> np.ndarray:
        """(N, 3) gravity in S (m/s²) from the orientation columns of Z."""
        return gravity_in_sensor(self._frame(Z), self.orientation, self.gravity)

    def _regressor(self, g_S):
        zeros = np.zeros_like(g_S)
        return payload_regressor(zeros, zeros, -g_S)[:, :, STATIC_COLUMNS]

    def _drift(self, Z):
        if not self.temperature_in_ or self.temperature_reference_ is None:
            return 0.0
        return np.outer(Z[:, -1] - self.temperature_reference_, self.temperature_coefficients_)

    def _predict(self, Z):
        g_S = self.gravity_in_sensor(Z)
        if self.sensor_matrix_ is not None:
            m, h = self.correction_payload_[0], self.correction_payload_[1:4]
            W_S = np.hstack([m * g_S, np.cross(h, g_S)])
            return W_S @ self.sensor_matrix_.T + self.correction_bias_ + self._drift(Z)
        return self._regressor(g_S) @ self.parameters_ + self._drift(Z)

    def _predict_std(self, Z):
        var = np.broadcast_to(self.residual_rms_ ** 2, (len(Z), 6)).copy()
        if self.sensor_matrix_ is None:
            A = self._regressor(self.gravity_in_sensor(Z))
            var += np.einsum("nij,jk,nik->ni", A, self.covariance_, A)
        return np.sqrt(var)
