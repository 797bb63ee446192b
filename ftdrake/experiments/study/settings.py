"""The study's settings: what is tuned, the quick run's defaults, and each method's grid."""

from __future__ import annotations

from ... import conventions as col
from ...compensation.estimators.registry import entry
from ...compensation.estimators.tuning import grid_size, param_grid
from ...compensation.features import FEATURE_SETS
from .layout import FEATURES

#: The methods tuned by grid search, by their compensator's registry name (its grids).
TUNED = {"rf": "rf", "svr": "svr", "svr_scaled": "svr"}
#: The physics rows: the payload model that reads only the feature set's joint-state blocks.
PHYSICS_MODE = {"q": "static", "q,qd": "dynamic", "q,qd,qdd": "dynamic"}

SEGMENT_S = 4.0  # length of a grouped-CV segment (s): longer than a row's near copies
#: The hybrid's residual forest is not tuned (its grid would double the run time); these
#: settings smooth over the sensor noise that the residual mostly is.
HYBRID_RESIDUAL = {"n_estimators": 40, "max_features": 1.0, "min_samples_leaf": 5}

# Defaults: the quick study (`ftdrake study --quick`; see the package docstring).
TRAJECTORIES = 6  # per dataset
TEST_TRAJECTORIES = 2  # of those, held out whole
DURATION_S = 20.0  # per trajectory: one period of the reference motion's base frequency
TRAIN_HZ = 12.5  # training rows per second of log (the motion is below 1 Hz)
TEST_HZ = 100.0
SVR_MAX_ROWS = 2000
N_SPLITS = 5  # the study's 5-fold CV


def method_grid(preset, name: str):
    """The grid of registry name `name`: from a preset name, or a custom preset dict keyed by
    registry name or class name."""
    if isinstance(preset, str):
        return param_grid(preset, name)
    cls_name = entry(name).cls.__name__
    return preset[name] if name in preset else preset[cls_name]


def grid_sizes(preset) -> dict:
    """Candidates per tuned estimator (keyed by class name) and feature set (max_features is
    clipped to the set)."""
    n = col.N_JOINTS
    by_class = {entry(name).cls.__name__: name for name in set(TUNED.values())}
    return {cls_name: {f: grid_size(method_grid(preset, name), name, FEATURE_SETS[f] * n)
                       for f in FEATURES} for cls_name, name in sorted(by_class.items())}
