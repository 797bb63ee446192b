"""Fast predictors for a 1 kHz control loop: a numba-compiled forest and a numpy kernel model.

scikit-learn's ``predict`` costs milliseconds for one row (input validation, joblib, one
Python call per tree). The predictors here take the full ``[q, q̇, q̈]`` row (3n values, rad,
rad/s, rad/s²), select the model's feature columns themselves and return the k outputs (a
wrench in N and N·m, or whatever the model was trained on), equal to scikit-learn's
``predict`` to 1e-9:

* :class:`CompiledForest` – regression forests (one per output, or one multi-output forest)
  flattened into arrays and walked by numba.
* :class:`FastKernelModel` – SVRs as an input affine map, kernel expansions against stored
  points, and an output affine map.
* :class:`CompiledGaussianProcess` – a ``GPRCompensator``'s mean *and* standard deviation
  for one row by numba (kernel row, then forward substitution with the stored Cholesky
  factor), equal to its ``predict`` and ``predict_std``.
* :mod:`.payload` – the physics payload model's row (serial-chain kinematics, regressor row,
  mean and parameter variance) from two packed arrays; ``PhysicsPayloadCompensator``'s
  row predictor.
* :class:`CompiledHybrid` – a ``HybridCompensator``'s payload model and forest residual in one
  numba call per row, mean and std, equal to its ``predict`` and ``predict_std``.
* :mod:`.loop` – a whole ``CompensatorSystem`` sample in one compiled call (input checks, q̈
  estimate, prediction, compensated wrench): what a compensator's ``fused_loop_update()``
  returns.

All have ``predict(X)`` for (N, 3n) → (N, k) and ``predict_one(x, out=None)`` for
(3n,) → (k,); all raise ``ValueError`` on a wrong column count or a NaN/inf input. They
always return 2-D / 1-D k-vectors, also for a model fitted on a 1-D target (k = 1).
A compensator builds its own with ``compiled_predictor()`` (the compensator protocol, see
:mod:`ftdrake.compensation.estimators.base`).
"""

from .forest import CompiledForest, FlatForest, flatten_forests, forest_accumulate
from .gp import CompiledGaussianProcess
from .hybrid import CompiledHybrid
from .kernel import FastKernelModel, KernelExpansion

__all__ = [
    "CompiledForest",
    "CompiledGaussianProcess",
    "CompiledHybrid",
    "FastKernelModel",
    "FlatForest",
    "KernelExpansion",
    "flatten_forests",
    "forest_accumulate",
]
