"""Compiled kinematics of the sensor frame on a serial chain.

:class:`SerialChain` is extracted once from a finalized ``MultibodyPlant``: the joints on the
path from the world to the body of frame S, each with the fixed pose ``X_PF`` of its parent
frame F in the parent body P, ``X_CM`` of its child frame M in the child body C, its type and
axis and where its coordinates are in the arm's q and v, plus ``X_BS`` of S in its body B.
From these, numba-compiled code computes by forward recursion what
:func:`ftdrake.physics.rigid_body.sensor_kinematics` computes with Drake's Jacobians —

    R_WS, ω_WS_S, α_WS_S, a_WSo_S (translational acceleration of So), g_S

(everything but R_WS expressed in S) — in about a microsecond per row instead of hundreds.

The recursion, frame by frame, carries the pose of the current frame A in W and the angular
velocity/acceleration of A and the velocity/acceleration of its origin, all expressed in W.
A fixed offset ``X_AB`` (B on the same body) shifts the origin by ``r = R_WA·p_AB``::

    v_WBo = v_WAo + ω × r,   a_WBo = a_WAo + α × r + ω × (ω × r)

A revolute joint (unit axis â in F, rotation θ about it, Mo = Fo) adds ``â_W θ̇`` to ω and
``â_W θ̈ + ω_WF × â_W θ̇`` to α. A prismatic joint (translation d along â in F) moves Mo by
``r = â_W d`` as a fixed offset would, plus ``â_W ḋ`` to v and ``2 ω × â_W ḋ + â_W d̈`` to a.
Welds are fixed offsets. Consecutive fixed offsets (``X_CM⁻¹`` of one joint, ``X_PF`` of the
next, welds between) are composed once at extraction.
"""

from __future__ import annotations

import dataclasses as dc

import numba
import numpy as np

from ..conventions import GRAVITY_W
from ..errors import RobotModelError
from .rigid_body import SensorKinematics

#: Joint types the compiled chain handles (Drake's ``Joint.type_name()``).
REVOLUTE, PRISMATIC, WELD = "revolute", "prismatic", "weld"
_KIND = {REVOLUTE: 0, PRISMATIC: 1}


@dc.dataclass(frozen=True)
class ChainJoint:
    """One joint on the path from the world to frame S, as Drake defines it."""

    name: str
    type: str  # "revolute", "prismatic" or "weld"
    X_PF: np.ndarray  # (4, 4) pose of frame F in the parent body P
    X_CM: np.ndarray  # (4, 4) pose of frame M in the child body C
    X_FM: np.ndarray | None  # (4, 4) fixed pose of M in F (welds only)
    axis_F: np.ndarray | None  # (3,) unit axis in F (revolute, prismatic)
    q_index: int  # index of its coordinate in the arm's q (-1 for a weld)
    v_index: int  # index of its rate in the arm's v (-1 for a weld)


@dc.dataclass(frozen=True)
class SerialChain:
    """The serial chain from the world to frame S, ready for the compiled kernels.

    ``joints`` lists every joint from the world outwards (welds included); ``X_BS`` is S in
    its body. The kernel arrays: ``X_pre[i]`` (3 × 4, ``[R | p]``) is the fixed pose of the
    i-th moving joint's frame F in the previous moving joint's frame M (the world for the
    first) and ``X_pre[-1]`` that of S in the last M; ``kinds`` (0 revolute, 1 prismatic),
    ``axes`` (in F), ``q_index``/``v_index`` per moving joint. ``num_positions`` and
    ``num_velocities`` are the sizes of the q and v the rows hold (the arm's).
    """

    joints: tuple[ChainJoint, ...]
    X_BS: np.ndarray
    X_pre: np.ndarray  # (n + 1, 3, 4)
    kinds: np.ndarray  # (n,) int64
    axes: np.ndarray  # (n, 3)
    q_index: np.ndarray  # (n,) int64
    v_index: np.ndarray  # (n,) int64
    num_positions: int
    num_velocities: int

    @classmethod
    def from_plant(cls, plant, frame_S, instance=None) -> SerialChain:
        """Extracts the chain of `frame_S` from finalized `plant`; rows are `instance`'s q, v
        (the whole plant's for None). Raises RobotModelError when the path from the world
        to S holds a joint type other than revolute, prismatic or weld (e.g. a floating
        base), a body with several inboard joints, or a joint outside `instance`."""
        if not plant.is_finalized():
            raise RobotModelError("the plant must be finalized to extract its serial chain")
        joints = _path_from_world(plant, frame_S.body())
        q_of, v_of = _local_indices(plant, instance)
        chain = []
        for joint in joints:
            kind = joint.type_name()
            X_PF = joint.frame_on_parent().GetFixedPoseInBodyFrame().GetAsMatrix4()
            X_CM = joint.frame_on_child().GetFixedPoseInBodyFrame().GetAsMatrix4()
            if kind == WELD:
                chain.append(ChainJoint(joint.name(), kind, X_PF, X_CM,
                                        joint.X_FM().GetAsMatrix4(), None, -1, -1))
                continue
            if kind not in _KIND:
                raise RobotModelError(
                    f"joint {joint.name()!r} on the path from the world to frame "
                    f"{frame_S.name()!r} is a {kind} joint; the compiled serial chain handles "
                    "revolute, prismatic and weld joints (a floating or mobile base is not a "
                    "serial arm: weld the base to the world, e.g. with base_frame)")
            g_q, g_v = joint.position_start(), joint.velocity_start()
            if g_q not in q_of or g_v not in v_of:
                raise RobotModelError(
                    f"joint {joint.name()!r} on the path to frame {frame_S.name()!r} is not in "
                    f"model instance {plant.GetModelInstanceName(instance)!r} whose q, v the "
                    "rows hold")
            axis = joint.revolute_axis() if kind == REVOLUTE else joint.translation_axis()
            chain.append(ChainJoint(joint.name(), kind, X_PF, X_CM, None,
                                    np.asarray(axis, dtype=float).copy(), q_of[g_q], v_of[g_v]))
        X_BS = frame_S.GetFixedPoseInBodyFrame().GetAsMatrix4()
        n_q = plant.num_positions(instance) if instance is not None else plant.num_positions()
        n_v = plant.num_velocities(instance) if instance is not None else plant.num_velocities()
        return cls._compile(tuple(chain), X_BS, n_q, n_v)

    @classmethod
    def _compile(cls, joints, X_BS, n_q, n_v) -> SerialChain:
        pre, kinds, axes, qi, vi = [], [], [], [], []
        X = np.eye(4)  # the pose of the current body frame in the last moving joint's M
        for joint in joints:
            X = X @ joint.X_PF
            if joint.type == WELD:
                X = X @ joint.X_FM @ np.linalg.inv(joint.X_CM)
                continue
            pre.append(X[:3].copy())
            kinds.append(_KIND[joint.type])
            axes.append(joint.axis_F)
            qi.append(joint.q_index)
            vi.append(joint.v_index)
            X = np.linalg.inv(joint.X_CM)
        pre.append((X @ X_BS)[:3].copy())
        return cls(joints, X_BS, np.ascontiguousarray(pre), np.asarray(kinds, dtype=np.int64),
                   np.asarray(axes, dtype=float).reshape(-1, 3),
                   np.asarray(qi, dtype=np.int64), np.asarray(vi, dtype=np.int64), n_q, n_v)

    def with_joint_columns(self, names, fixed=None) -> tuple[SerialChain, list[str]]:
        """This chain with rows that hold the joints `names` in that order (a log's position
        columns) and every other joint on the path held still.

        A moving joint of the path not in `names` becomes a weld at its value in `fixed`
        (a mapping name → rad for revolute, m for prismatic), 0 when `fixed` has none; the
        second value returned lists those held at 0 that way. Names in `names` that are not
        on the path (a head or finger joint) take a column and move nothing. Rows then have
        ``len(names)`` positions and as many velocities.
        """
        names, fixed = list(names), dict(fixed or {})
        joints, defaulted = [], []
        for joint in self.joints:
            if joint.type == WELD:
                joints.append(joint)
            elif joint.name in names:
                i = names.index(joint.name)
                joints.append(dc.replace(joint, q_index=i, v_index=i))
            else:
                if joint.name not in fixed:
                    defaulted.append(joint.name)
                X_FM = joint_pose(joint.type, joint.axis_F, float(fixed.get(joint.name, 0.0)))
                joints.append(ChainJoint(joint.name, WELD, joint.X_PF, joint.X_CM, X_FM, None,
                                         -1, -1))
        return self._compile(tuple(joints), self.X_BS, len(names), len(names)), defaulted

    @property
    def num_moving_joints(self) -> int:
        return len(self.kinds)

    def kernel_args(self) -> tuple:
        """The arrays the compiled kernels take, in their order."""
        return self.X_pre, self.kinds, self.axes, self.q_index, self.v_index

    def evaluate(self, q, v, vdot, gravity_W=GRAVITY_W):
        """Rows (N × n) of q, v, v̇ → :class:`~ftdrake.physics.rigid_body.SensorKinematics`."""
        q, v, vdot = (np.ascontiguousarray(np.atleast_2d(np.asarray(a, dtype=float)))
                      for a in (q, v, vdot))
        if q.shape[1] != self.num_positions or v.shape[1] != self.num_velocities or \
                vdot.shape != v.shape or len(v) != len(q):
            raise ValueError(f"rows of q, v, v̇ must have {self.num_positions}, "
                             f"{self.num_velocities}, {self.num_velocities} columns and equal "
                             f"lengths; got {q.shape}, {v.shape}, {vdot.shape}")
        n = len(q)
        R = np.empty((n, 3, 3))
        out = np.empty((n, 4, 3))
        sensor_kinematics_batch(q, v, vdot, np.asarray(gravity_W, dtype=float),
                                *self.kernel_args(), R, out)
        return SensorKinematics(R, out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy(),
                                out[:, 3].copy())


def joint_pose(kind: str, axis, value: float) -> np.ndarray:
    """(4, 4) pose X_FM of a revolute (`value` in rad about `axis`) or prismatic (`value` in m
    along `axis`) joint's frame M in its frame F, as Drake defines them."""
    axis = np.asarray(axis, dtype=float)
    X = np.eye(4)
    if kind == PRISMATIC:
        X[:3, 3] = axis * value
        return X
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    X[:3, :3] = np.eye(3) + np.sin(value) * K + (1 - np.cos(value)) * K @ K  # Rodrigues
    return X


def _path_from_world(plant, body) -> list:
    """The joints from the world to `body`, world first."""
    inboard = {}
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        child = int(joint.child_body().index())
        if child in inboard:
            raise RobotModelError(
                f"body {joint.child_body().name()!r} is the child of joints "
                f"{inboard[child].name()!r} and {joint.name()!r}: not a serial chain")
        inboard[child] = joint
    world = int(plant.world_body().index())
    path, current = [], body
    while int(current.index()) != world:
        joint = inboard.get(int(current.index()))
        if joint is None:
            raise RobotModelError(
                f"body {current.name()!r} has no inboard joint: the chain to frame S does not "
                "reach the world")
        path.append(joint)
        current = joint.parent_body()
        if len(path) > plant.num_joints():
            raise RobotModelError("the joints form a loop: not a serial chain")
    return path[::-1]


def _local_indices(plant, instance):
    """Maps of the plant's q and v indices to the rows' (the instance's) indices."""
    if instance is None:
        return ({i: i for i in range(plant.num_positions())},
                {i: i for i in range(plant.num_velocities())})
    q_global = plant.GetPositionsFromArray(instance, np.arange(plant.num_positions(), dtype=float))
    v_global = plant.GetVelocitiesFromArray(instance,
                                            np.arange(plant.num_velocities(), dtype=float))
    return ({int(g): i for i, g in enumerate(q_global)},
            {int(g): i for i, g in enumerate(v_global)})


# -- compiled kernels ----------------------------------------------------------------------------
@numba.njit(cache=True, inline="always")
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True)
def _shift(R, p, w, al, v, a, X, r, t1, t2):
    """Moves the current frame by the fixed offset X (3 × 4) in it: updates R, p, v, a."""
    for i in range(3):
        r[i] = R[i, 0] * X[0, 3] + R[i, 1] * X[1, 3] + R[i, 2] * X[2, 3]
    _cross(w, r, t1)
    _cross(w, t1, t2)
    for i in range(3):
        v[i] += t1[i]
        a[i] += t2[i]
        p[i] += r[i]
    _cross(al, r, t1)
    for i in range(3):
        a[i] += t1[i]
    for i in range(3):
        r0, r1, r2 = R[i, 0], R[i, 1], R[i, 2]
        for j in range(3):
            t1[j] = r0 * X[0, j] + r1 * X[1, j] + r2 * X[2, j]
        for j in range(3):
            R[i, j] = t1[j]


@numba.njit(cache=True)
def sensor_kinematics_row(q, v, vdot, gravity_W, X_pre, kinds, axes, q_index, v_index,
                          R_WS, out):
    """One row: R_WS (3 × 3) and out (4 × 3) = [ω_WS_S, α_WS_S, a_WSo_S, g_S]."""
    R = R_WS
    R[:, :] = 0.0
    R[0, 0] = R[1, 1] = R[2, 2] = 1.0
    # One allocation for the 3-vectors and Rj (rows of `work`, C-contiguous views): the
    # kernel runs once per 1 kHz sample, where small allocations cost much of its time.
    work = np.zeros((12, 3))
    p, w, al, vel, acc = work[0], work[1], work[2], work[3], work[4]
    r, t1, t2, u = work[5], work[6], work[7], work[8]
    Rj = work[9:12]
    for k in range(len(kinds)):
        _shift(R, p, w, al, vel, acc, X_pre[k], r, t1, t2)
        for i in range(3):  # the axis in W
            u[i] = R[i, 0] * axes[k, 0] + R[i, 1] * axes[k, 1] + R[i, 2] * axes[k, 2]
        x, xd, xdd = q[q_index[k]], v[v_index[k]], vdot[v_index[k]]
        if kinds[k] == 0:
            _revolute(R, w, al, u, axes[k], x, xd, xdd, Rj, t1, t2)
        else:
            _prismatic(p, w, al, vel, acc, u, x, xd, xdd, r, t1, t2)
    _shift(R, p, w, al, vel, acc, X_pre[len(kinds)], r, t1, t2)
    for j in range(3):  # express in S: x_S = R_WSᵀ x_W
        out[0, j] = R[0, j] * w[0] + R[1, j] * w[1] + R[2, j] * w[2]
        out[1, j] = R[0, j] * al[0] + R[1, j] * al[1] + R[2, j] * al[2]
        out[2, j] = R[0, j] * acc[0] + R[1, j] * acc[1] + R[2, j] * acc[2]
        out[3, j] = R[0, j] * gravity_W[0] + R[1, j] * gravity_W[1] + R[2, j] * gravity_W[2]


@numba.njit(cache=True)
def _revolute(R, w, al, u, axis, x, xd, xdd, Rj, t1, t2):
    """Across a revolute joint of angle x about `axis` (û = the axis in W):
    R_WM = R_WF · Rot(â, x), Mo = Fo; ω += û ẋ, α += û ẍ + ω × û ẋ."""
    _cross(w, u, t1)
    for i in range(3):
        al[i] += u[i] * xdd + t1[i] * xd
        w[i] += u[i] * xd
    s, c = np.sin(x), np.cos(x)
    ax, ay, az = axis[0], axis[1], axis[2]
    C = 1.0 - c
    Rj[0, 0] = c + ax * ax * C
    Rj[0, 1] = ax * ay * C - az * s
    Rj[0, 2] = ax * az * C + ay * s
    Rj[1, 0] = ay * ax * C + az * s
    Rj[1, 1] = c + ay * ay * C
    Rj[1, 2] = ay * az * C - ax * s
    Rj[2, 0] = az * ax * C - ay * s
    Rj[2, 1] = az * ay * C + ax * s
    Rj[2, 2] = c + az * az * C
    for i in range(3):
        r0, r1, r2 = R[i, 0], R[i, 1], R[i, 2]
        for j in range(3):
            t2[j] = r0 * Rj[0, j] + r1 * Rj[1, j] + r2 * Rj[2, j]
        for j in range(3):
            R[i, j] = t2[j]


@numba.njit(cache=True)
def _prismatic(p, w, al, vel, acc, u, x, xd, xdd, r, t1, t2):
    """Across a prismatic joint of travel x along û (in W): Mo = Fo + û x, R_WM = R_WF."""
    for i in range(3):
        r[i] = u[i] * x
    _cross(w, r, t1)
    _cross(w, t1, t2)
    for i in range(3):
        vel[i] += t1[i] + u[i] * xd
        acc[i] += t2[i] + u[i] * xdd
        p[i] += r[i]
    _cross(al, r, t1)
    _cross(w, u, t2)
    for i in range(3):
        acc[i] += t1[i] + 2.0 * t2[i] * xd


@numba.njit(cache=True)
def sensor_kinematics_batch(q, v, vdot, gravity_W, X_pre, kinds, axes, q_index, v_index,
                            R_WS, out):
    """N rows: R_WS (N × 3 × 3) and out (N × 4 × 3), as :func:`sensor_kinematics_row`."""
    for n in range(q.shape[0]):
        sensor_kinematics_row(q[n], v[n], vdot[n], gravity_W, X_pre, kinds, axes, q_index,
                              v_index, R_WS[n], out[n])


@numba.njit(cache=True)
def joint_frames_in_sensor_row(q, X_pre, kinds, axes, q_index, out):
    """One row: out (m + 1, 3, 4) = ``X_SMk`` ([R | p], the pose in S of each moving joint's
    frame M_k, k < m) and ``X_SW`` (the world's, k = m); only q moves the frames."""
    m = len(kinds)
    R = np.zeros((3, 3))
    R[0, 0] = R[1, 1] = R[2, 2] = 1.0
    work = np.zeros((12, 3))
    p, w, al, vel, acc = work[0], work[1], work[2], work[3], work[4]
    r, t1, t2, u = work[5], work[6], work[7], work[8]
    Rj = work[9:12]
    X_WM = np.empty((m, 3, 4))
    for k in range(m):
        _shift(R, p, w, al, vel, acc, X_pre[k], r, t1, t2)
        for i in range(3):
            u[i] = R[i, 0] * axes[k, 0] + R[i, 1] * axes[k, 1] + R[i, 2] * axes[k, 2]
        if kinds[k] == 0:
            _revolute(R, w, al, u, axes[k], q[q_index[k]], 0.0, 0.0, Rj, t1, t2)
        else:
            _prismatic(p, w, al, vel, acc, u, q[q_index[k]], 0.0, 0.0, r, t1, t2)
        X_WM[k, :, :3] = R
        X_WM[k, :, 3] = p
    _shift(R, p, w, al, vel, acc, X_pre[m], r, t1, t2)
    for k in range(m + 1):  # X_SMk = X_WSᵀ X_WMk; X_SW = X_WS⁻¹
        for i in range(3):
            for j in range(3):
                if k < m:
                    out[k, i, j] = (R[0, i] * X_WM[k, 0, j] + R[1, i] * X_WM[k, 1, j]
                                    + R[2, i] * X_WM[k, 2, j])
                else:
                    out[k, i, j] = R[j, i]
            if k < m:
                d0, d1, d2 = X_WM[k, 0, 3] - p[0], X_WM[k, 1, 3] - p[1], X_WM[k, 2, 3] - p[2]
            else:
                d0, d1, d2 = -p[0], -p[1], -p[2]
            out[k, i, 3] = R[0, i] * d0 + R[1, i] * d1 + R[2, i] * d2


@numba.njit(cache=True)
def joint_frames_in_sensor_batch(q, X_pre, kinds, axes, q_index, out):
    """N rows of :func:`joint_frames_in_sensor_row`: out (N, m + 1, 3, 4)."""
    for n in range(q.shape[0]):
        joint_frames_in_sensor_row(q[n], X_pre, kinds, axes, q_index, out[n])
