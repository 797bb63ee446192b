"""What the study's tables hold: datasets, methods, feature sets, wrench axes and metrics."""

from __future__ import annotations

from ... import conventions as col
from ...compensation.features import FEATURE_SETS

DATASETS = ("reference", "z_rich")
METHODS = ("rf", "svr", "svr_scaled", "hybrid", "physics")
METRICS = ("mse", "nmse", "variance_score", "rms_vs_truth", "rms_over_noise")
FEATURES = tuple(FEATURE_SETS)  # "q", "q,qd", "q,qd,qdd"
AXES = col.WRENCH_AXES
