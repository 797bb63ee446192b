"""A cable or hose tethered to the tool: the configuration-dependent pull, identified.

A cable clipped to the tool at a point Q and held at a point P on a link of the arm (or on
the world: a cable to the cabinet) pulls the tool along the line Q → P with a tension that
grows with the line's length ℓ. To first order, an elastic tether:

    tension = k·(ℓ − ℓ0),   d_S = p_SP − p_SQ,  ℓ = |d_S|,  u = d_S / ℓ
    F_S = k·d_S − (k·ℓ0)·u,   T_So = p_SQ × F_S

(everything in S; the sensor reads this wrench with the tool's, like any force on the tool).
Given the geometry — which frame holds P, where P is in it, where Q is in S — the wrench is
linear in ``t = [k, k·ℓ0]`` (N/m, N): two regressor columns ``[d; Q×d]`` and ``[−u; −Q×u]``
(:func:`tether_columns`), which the payload's linear fit takes with its own. The geometry is
nonlinear: :func:`fit_tether_geometry` finds it by variable projection (for each candidate
frame, ``scipy.optimize.least_squares`` over P and Q with every linear parameter solved
for at each step), from a few starts per frame, and keeps the frame that explains the most.

A tether is a model of a class of cables, not of one: it has no term for a cable's bending
stiffness, slack (a cable pushes as little as it can), friction or the hanging part's sag,
and a tension that is only linear in the length. The hanging part's weight is the payload
model's weight carried without inertia. Frames: P in a moving joint's child frame M (the
frame :class:`~ftdrake.physics.chain.SerialChain` recurses through, named by its joint) or in
the world; Q in S; metres.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...errors import ConfigError

#: The frame name of an anchor on the world (a cable to a cabinet or a boom).
WORLD = "world"
#: Rows the geometry search uses (evenly spaced over the data): the search solves the
#: linear fit some thousands of times.
SEARCH_ROWS = 3000
#: Frames searched from every start (the others from the frame's origin only).
REFINED_FRAMES = 3
_STARTS_M = np.array([[0.0, 0.0, 0.0], [0.15, 0.0, 0.0], [0.0, 0.15, 0.0], [0.0, 0.0, 0.15],
                      [-0.15, 0.0, 0.0], [0.0, -0.15, 0.0], [0.0, 0.0, -0.15]])


def candidate_frames(option: str, names: list[str]) -> list[str]:
    """The frames to search for the option ``tether`` (``"auto"``: all of `names`; else the
    one frame it names); a name not among `names` is refused with the names it may take."""
    if option == "auto":
        return list(names)
    if option not in names:
        raise ConfigError(
            f"tether: {option!r} is no frame a tether can be fixed in; give 'auto', "
            f"'{WORLD}' or one of the moving joints {', '.join(n for n in names if n != WORLD)}")
    return [option]


@dc.dataclass(frozen=True)
class TetherGeometry:
    """Where the tether is: `frame` (a moving joint's name: P is fixed in its child frame M;
    or ``"world"``), ``p_FP`` (m, in that frame) and ``p_SQ`` (m, in S)."""

    frame: str
    p_FP: tuple[float, float, float]
    p_SQ: tuple[float, float, float]


def tether_columns(X_SF, p_FP, p_SQ) -> np.ndarray:
    """(N, 6, 2): the wrench in S of a tether of unit ``k`` and unit ``k·ℓ0`` for the poses
    ``X_SF`` (N, 3, 4) of the anchor's frame in S (see the module docstring)."""
    X_SF = np.asarray(X_SF, dtype=float)
    p_FP, p_SQ = np.asarray(p_FP, dtype=float), np.asarray(p_SQ, dtype=float)
    d = X_SF[:, :, :3] @ p_FP + X_SF[:, :, 3] - p_SQ
    length = np.linalg.norm(d, axis=1, keepdims=True)
    u = d / np.maximum(length, 1e-9)
    C = np.empty((len(d), 6, 2))
    C[:, :3, 0], C[:, 3:, 0] = d, np.cross(p_SQ, d)
    C[:, :3, 1], C[:, 3:, 1] = -u, -np.cross(p_SQ, u)
    return C


@dc.dataclass(frozen=True)
class TetherSearch:
    """What :func:`fit_tether_geometry` found: the geometry and, per candidate frame, the
    weighted residual sum of squares it left (relative to the fit without a tether)."""

    geometry: TetherGeometry
    relative_cost: dict


def fit_tether_geometry(frames_S, frame_names, A, Y, weights, *, rows: int = SEARCH_ROWS,
                        refine_rotation: bool = False) -> TetherSearch:
    """The tether geometry that best explains the readings with the linear model.

    frames_S : (N, K, 3, 4) poses in S of the candidate frames (``frame_names``, K).
    A : (N, 6, p) the other columns (payload, biases, ...), in the frame of Y.
    Y : (N, 6) readings, in S; weights (6,): per axis, 1 / the residual's scale.
    refine_rotation : also refine, with the geometry, a rotation of the readings (3 more
        unknowns, a rotation vector): for readings rotated into S by a mounting rotation that
        was fitted without the tether, whose pull it took in part.
    """
    N = len(Y)
    take = np.unique(np.linspace(0, N - 1, min(rows, N)).astype(int))
    projection = _Complement(A[take], Y[take], np.asarray(weights, dtype=float))
    F_s = frames_S[take]
    y = projection.projected(np.zeros(3))
    base_cost = float(y @ y)
    n_rotation = 3 if refine_rotation else 0
    x_scale = np.concatenate([np.full(6, 0.1), np.full(n_rotation, 0.02)])
    fits = {}

    def search(k, starts):
        for start in starts:
            fit = least_squares(lambda x: projection.residual(F_s[:, k], x),
                                np.concatenate([start, np.zeros(3 + n_rotation)]),
                                x_scale=x_scale, max_nfev=300 if refine_rotation else 200)
            cost = float(fit.fun @ fit.fun)
            if cost < fits.get(k, (np.inf,))[0]:
                fits[k] = (cost, fit.x)

    # Every frame from its origin, then the most promising frames from the other starts
    # (a local minimum from one start is common; across frames the ranking rarely changes).
    for k in range(len(frame_names)):
        search(k, _STARTS_M[:1])
    for k in sorted(fits, key=lambda k: fits[k][0])[:REFINED_FRAMES]:
        search(k, _STARTS_M[1:])
    best = min(fits, key=lambda k: fits[k][0])
    x = fits[best][1]
    geometry = TetherGeometry(frame_names[best], tuple(map(float, x[:3])),
                              tuple(map(float, x[3:6])))
    return TetherSearch(geometry, {frame_names[k]: c / base_cost for k, (c, _) in fits.items()})


class _Complement:
    """The weighted readings and the linear fit's other columns, reduced once: for a
    geometry, only the tether's two columns are projected off the others' span (variable
    projection) and the 2-parameter fit solved."""

    def __init__(self, A, Y, w):
        self.w = w
        Aw = (A * w[None, :, None]).reshape(-1, A.shape[-1])
        Q, R = np.linalg.qr(Aw)
        keep = np.abs(np.diag(R)) > 1e-10 * np.abs(np.diag(R)).max()
        self.Q = np.ascontiguousarray(Q[:, keep])  # an orthonormal basis of the span
        self.Y = Y
        self._unrotated = self._project(Y)

    def _project(self, Y) -> np.ndarray:
        yw = (Y * self.w).reshape(-1)
        return yw - self.Q @ (self.Q.T @ yw)

    def projected(self, rotation_vector) -> np.ndarray:
        """The weighted readings, rotated by the rotation vector (forces and torques alike),
        off the other columns' span."""
        if not np.any(rotation_vector):
            return self._unrotated
        R = Rotation.from_rotvec(rotation_vector).as_matrix()
        return self._project(self.Y @ np.kron(np.eye(2), R).T)

    def residual(self, X_SF, x) -> np.ndarray:
        """The weighted residual with the tether of geometry x = [p_FP, p_SQ] added (and
        the readings rotated by x[6:9], when given)."""
        y = self.projected(x[6:9]) if len(x) > 6 else self._unrotated
        C = (tether_columns(X_SF, x[:3], x[3:6]) * self.w[None, :, None]).reshape(-1, 2)
        C = C - self.Q @ (self.Q.T @ C)
        t = np.linalg.lstsq(C, y, rcond=None)[0]
        return y - C @ t
