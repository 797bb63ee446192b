"""A scenario's trajectory: :func:`make_trajectory` picks the planner of
``TrajectoryConfig.kind`` and checks what it plans against the joint limits.

The kinds and their motions are :mod:`ftdrake.sim.trajectories`'s; ``task_covering`` is
planned by :mod:`ftdrake.sim.excitation`, which builds on that module's helpers and geometry
(so this dispatch lives above both).
"""

from __future__ import annotations

import numpy as np

from ..config import TrajectoryConfig
from ..errors import TrajectoryError
from .excitation import task_covering
from .trajectories import (
    CONTACT_KINDS,
    JointLimits,
    _contact,
    _free_motion,
    _within_limits,
    check_limits,
    study_motion,
)


def make_trajectory(config: TrajectoryConfig, home_q, limits: JointLimits, robot=None):
    """Builds and checks the trajectory `config.kind` starting and ending at `home_q`
    (q(t) in rad, a ``PiecewisePolynomial``).

    `robot` (a :class:`~ftdrake.sim.trajectories.RobotGeometry`) is needed for the contact
    kinds (inverse kinematics) and used to keep free motion clear of the environment.
    `config` is taken as valid (it is checked with its scenario, where that is loaded).
    Raises :class:`~ftdrake.errors.TrajectoryError` naming the limit or the clearance a
    motion breaks.
    """
    home_q = np.asarray(home_q, dtype=float)
    if np.any(home_q < limits.lower) or np.any(home_q > limits.upper):
        raise TrajectoryError(f"home_q {home_q.round(3).tolist()} is outside the joint limits")
    if config.kind == "study":
        traj = study_motion(config.duration_s, config.seed)
        if robot is not None and not robot.clear_of_environment(traj, dt=1.0):
            raise TrajectoryError("the study's motion hits the environment; use a scene "
                                  "without obstacles in its reach (see study_motion)")
    elif config.kind in CONTACT_KINDS:
        if robot is None:
            raise TrajectoryError(f"the {config.kind} kind needs the robot's geometry for IK")
        depth = config.press_depth_m if config.kind == "contact" else -config.rehearsal_height_m
        traj = _contact(config, depth, home_q, robot, limits)
    elif config.kind == "task_covering":
        traj = task_covering(config, home_q, limits, robot)
        if not (_within_limits(traj, limits, config.speed_fraction)
                and robot.clear_of_environment(traj)):
            raise TrajectoryError("the task_covering plan leaves the speed limits or the "
                                  "clearance between its samples; lower trajectory.speed_fraction")
    else:
        traj = _free_motion(config, home_q, limits, robot)
    check_limits(traj, limits)
    return traj


__all__ = ["make_trajectory"]
