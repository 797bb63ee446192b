"""The payload model's kinematics: the robot's serial chain to the sensor frame S, with
gravity, built once per robot description and never stored on an estimator (a model file
holds only the description).

Frames: S is the sensor's measuring frame; the chain's joint frames are each moving joint's
child frame M (:class:`~ftdrake.physics.chain.SerialChain`), named by the joint; poses are
(3, 4) ``[R | p]`` in metres.
"""

from __future__ import annotations

import functools

import numpy as np

from ...errors import RobotModelError
from ...physics.chain import SerialChain, joint_frames_in_sensor_batch
from ...physics.robot import (
    RobotDescription,
    check_joint_names,
    floating_base_hint,
    joint_count_message,
)
from .tether import WORLD


class PayloadKinematics:
    """The robot's serial chain to S and gravity (m/s², in the world)."""

    def __init__(self, chain: SerialChain, gravity, defaulted=(), count_message=None):
        self.chain = chain
        self.num_joints = self.n_joints = chain.num_positions
        self.gravity = np.asarray(gravity, dtype=float)
        self.defaulted = list(defaulted)  # joints on the path fixed at 0 by default
        self._count_message = count_message

    def count_message(self, n_data: int) -> str:
        """The error for rows of `n_data` joints (the model's joint names and the flags)."""
        if self._count_message is None:
            return f"the data has {n_data} joints; the robot model has {self.num_joints}"
        return self._count_message(n_data)

    def evaluate(self, q, v, vdot):
        return self.chain.evaluate(q, v, vdot, self.gravity)

    def anchor_frame_names(self) -> list[str]:
        """The frames a tether's far end may be fixed in: each moving joint's child frame M
        (by the joint's name), from the base outwards, then ``"world"``."""
        return [j.name for j in self.chain.joints if j.type != "weld"] + [WORLD]

    def anchor_frames_in_sensor(self, X) -> np.ndarray:
        """(N, K, 3, 4): the poses in S of :meth:`anchor_frame_names`' frames for the rows X
        (whose first columns are q, rad or m)."""
        chain = self.chain
        q = np.ascontiguousarray(np.asarray(X, dtype=float)[:, :chain.num_positions])
        out = np.empty((len(q), chain.num_moving_joints + 1, 3, 4))
        joint_frames_in_sensor_batch(q, chain.X_pre, chain.kinds, chain.axes, chain.q_index,
                                     out)
        return out


@functools.lru_cache(maxsize=8)
def kinematics_for(description: RobotDescription, gravity: tuple) -> PayloadKinematics:
    """The chain of `description`'s robot to its sensor frame (cached per description)."""
    plant, frame_S = description.build_plant()
    if description.joints:  # the log holds some joints; the others are welded where they stand
        check_joint_names(plant, description)
        chain, defaulted = SerialChain.from_plant(plant, frame_S).with_joint_columns(
            description.joints, dict(description.fixed_joints))
        return PayloadKinematics(chain, gravity, defaulted)
    if plant.num_positions() != plant.num_velocities():
        raise RobotModelError(
            f"robot model {description.label} has {plant.num_positions()} positions but "
            f"{plant.num_velocities()} velocities ({floating_base_hint(plant)}): the "
            "[q, q̇, q̈] rows need one coordinate per joint")
    label = description.label
    return PayloadKinematics(SerialChain.from_plant(plant, frame_S), gravity,
                             count_message=functools.partial(joint_count_message, plant,
                                                             label=label))
