"""The one input layout every compensator takes, and the study's feature sets.

``X`` is always ``[q, q̇, q̈]``: N rows × 3n columns for an n-joint robot (rad, rad/s,
rad/s²). A compensator's ``features`` parameter picks which blocks it actually uses:

* ``"q"``          – joint positions only (n features)
* ``"q,qd"``       – positions and velocities (2n)
* ``"q,qd,qdd"``   – positions, velocities and accelerations (3n)

:func:`describe_nonfinite` names the rows of an input that hold NaN or infinity (the message
fitting and scoring refuse them with).
"""

from __future__ import annotations

import numpy as np

FEATURE_SETS: dict[str, int] = {"q": 1, "q,qd": 2, "q,qd,qdd": 3}


def check_feature_set(features: str) -> int:
    """Returns how many n-blocks `features` uses; raises ValueError on an unknown name."""
    try:
        return FEATURE_SETS[features]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown feature set {features!r}; expected one of {sorted(FEATURE_SETS)}"
        ) from None


def joints_in_layout(n_columns: int) -> int:
    """Number of joints n for an X with `n_columns` = 3n columns."""
    if n_columns % 3 != 0 or n_columns == 0:
        raise ValueError(
            f"X must have 3n columns laid out as [q, qd, qdd]; got {n_columns} columns"
        )
    return n_columns // 3


def select_features(X: np.ndarray, features: str) -> np.ndarray:
    """Columns of the [q, qd, qdd] layout that feature set `features` uses."""
    blocks = check_feature_set(features)
    n = joints_in_layout(X.shape[1])
    return X[:, : blocks * n]


def feature_names(features: str, n_joints: int) -> list[str]:
    """Human-readable names of the selected columns, e.g. ``["q_0", ..., "qd_6"]``."""
    blocks = check_feature_set(features)
    prefixes = ("q", "qd", "qdd")[:blocks]
    return [f"{p}_{i}" for p in prefixes for i in range(n_joints)]


def stack_layout(q: np.ndarray, qd: np.ndarray | None = None, qdd: np.ndarray | None = None):
    """Builds the [q, qd, qdd] layout; missing blocks are filled with zeros of q's shape."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    qd = np.zeros_like(q) if qd is None else np.atleast_2d(np.asarray(qd, dtype=float))
    qdd = np.zeros_like(q) if qdd is None else np.atleast_2d(np.asarray(qdd, dtype=float))
    if not (q.shape == qd.shape == qdd.shape):
        raise ValueError(f"q, qd, qdd shapes differ: {q.shape}, {qd.shape}, {qdd.shape}")
    return np.hstack([q, qd, qdd])


def describe_nonfinite(a: np.ndarray, name: str) -> str | None:
    """A message naming how many rows of `a` hold NaN/inf and the first one, or None."""
    bad = ~np.isfinite(a)
    if a.ndim > 1:
        bad = bad.any(axis=tuple(range(1, a.ndim)))
    if not bad.any():
        return None
    rows = np.flatnonzero(bad)
    return (
        f"Input {name} contains NaN or infinity in {rows.size} of {a.shape[0]} rows "
        f"(first at row {rows[0]}); clean or drop them explicitly before fitting"
    )
