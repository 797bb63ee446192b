"""Input checks shared by the compiled predictors: the ``[q, q̇, q̈]`` row layout."""

from __future__ import annotations

import numpy as np

from ..features import check_feature_set


def layout_error(shape, n_joints: int) -> ValueError:
    return ValueError(
        f"expected the [q, qd, qdd] layout with {3 * n_joints} columns for {n_joints} joints; "
        f"got an input of shape {shape}"
    )


def checked_rows(X, n_joints: int) -> np.ndarray:
    """`X` as a C-contiguous float64 (N, 3n) array; ValueError on a bad shape or NaN/inf."""
    X = np.ascontiguousarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3 * n_joints:
        raise layout_error(X.shape, n_joints)
    bad = ~np.isfinite(X).all(axis=1)
    if bad.any():
        rows = np.flatnonzero(bad)
        raise ValueError(
            f"X contains NaN or infinity in {rows.size} of {len(X)} rows "
            f"(first at row {rows[0]}); no prediction is made from such a state"
        )
    return X


def checked_row(x, n_joints: int) -> np.ndarray:
    """`x` as a C-contiguous float64 (3n,) array; ValueError on a bad shape (not NaN)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.shape != (3 * n_joints,):
        raise layout_error(x.shape, n_joints)
    return x


def nonfinite_error(x: np.ndarray) -> ValueError:
    column = int(np.flatnonzero(~np.isfinite(x))[0])
    return ValueError(f"x contains NaN or infinity (first at column {column}): {x}")


def joints_for(n_used: int, features: str, n_joints: int | None) -> int:
    """Joint count n from the model's `n_used` input columns; checks a given `n_joints`."""
    blocks = check_feature_set(features)
    if n_used % blocks or (n_joints is not None and n_used != blocks * n_joints):
        expected = "3n" if n_joints is None else blocks * n_joints
        raise ValueError(
            f"the model takes {n_used} inputs, which does not fit features={features!r} "
            f"({blocks} blocks of n joints; expected {expected})"
        )
    return n_used // blocks
