"""Live mistakes named with their fix: joint positions in degrees, a wrong message type on a
channel or topic, a driver's rate far from the configured one.

The station (:class:`~ftdrake.hardware.core.StationCore`) and its transports call these; each
returns the words a user reads (a fault's detail or a warning), naming the config key and the
fix. Nothing here is on the per-message path except :meth:`JointBounds.check` (one vector
comparison per joint-state message) and :meth:`RateCheck.on_sample` (a counter).

* **Degrees.** :func:`joint_bounds` gives, per joint, the largest |q| (rad) a radian stream
  can read on this model: the robot's joint limit (+ :data:`LIMIT_MARGIN_RAD`) where the
  model carries a robot whose joint has finite limits, else the larger of 2π and
  :data:`TRAINING_FACTOR` × the largest |q| of the model's training range
  (``input_min_``/``input_max_``). A joint state beyond it is a fault: ``degrees`` when the
  same values read as degrees (× π/180) are within the bounds ("joint state in degrees?"),
  else ``joint_range``.
* **Wrong type.** :func:`lcm_type_found` names the ``drake.lcmt_*`` type whose fingerprint
  an undecodable LCM message carries; the ROS 2 station asks DDS discovery for the types
  published on its input topics (:func:`ros2_type_name`).
* **Rate.** :class:`RateCheck` measures the F/T stream's rate over its first second of
  stamps; farther than :data:`RATE_TOLERANCE` (relative) from ``chain.sensor.rate_hz`` it
  gives a warning naming both rates and the key.
"""

from __future__ import annotations

import functools
import math
import operator
from typing import NamedTuple

import numpy as np

#: A joint may read this far (rad) beyond its limit in the robot's description.
LIMIT_MARGIN_RAD = 0.1
#: Without a robot limit, a joint may read up to this times its training range's largest |q|
#: (and never less than 2π).
TRAINING_FACTOR = 3.0
#: A measured F/T rate within this relative distance of chain.sensor.rate_hz is "as
#: configured".
RATE_TOLERANCE = 0.2
#: Seconds of F/T stamps the rate is measured over.
RATE_WINDOW_S = 1.0


class JointBounds(NamedTuple):
    """Per joint: the largest |q| (rad) radians can read (`limit`), where it comes from
    (`source`, words per joint) and the joints' names (for messages; "joint k" if unknown)."""

    limit: np.ndarray
    source: tuple[str, ...]
    names: tuple[str, ...]

    def check(self, q) -> tuple[str, str] | None:
        """None when every |q_j| ≤ limit_j, else (reason, detail): ``degrees`` when q read
        as degrees fits, ``joint_range`` otherwise."""
        values = q.tolist() if hasattr(q, "tolist") else list(q)
        if all(map(operator.le, map(abs, values), self.limit.tolist())):  # per message: cheap
            return None
        j = int(np.argmax(np.abs(q) / self.limit))
        name, value, bound = self.names[j], float(q[j]), float(self.limit[j])
        if (np.abs(np.radians(q)) <= self.limit).all():
            return "degrees", (
                f"joint state in degrees? {name} reads {value:.2f}, more than radians can be "
                f"on this model (|q| ≤ {bound:.2f} rad: {self.source[j]}); as degrees it is "
                f"{math.radians(value):.3f} rad. Fix: send radians (sensor_msgs/JointState "
                "and drake's lcmt_*_status carry rad): convert in the driver or its bridge")
        return "joint_range", (
            f"{name} reads {value:.2f} rad, beyond what it can be on this model "
            f"(|q| ≤ {bound:.2f} rad: {self.source[j]}), in radians or degrees. Fix: check "
            "the joint order and units of the joint state (ros2.joint_names / "
            "lcm.joint_state_type)")


def joint_bounds(model, n: int, names=None) -> JointBounds:
    """The JointBounds of `model` for `n` joints (see the module); `names` label them."""
    names = tuple(names) if names is not None and len(names) == n else tuple(
        f"joint {k + 1}" for k in range(n))
    limit = np.full(n, 2 * math.pi)
    source = ["2π"] * n
    lo, hi = getattr(model, "input_min_", None), getattr(model, "input_max_", None)
    if lo is not None and hi is not None and len(lo) >= n and len(hi) >= n:
        span = np.maximum(np.abs(np.asarray(lo[:n], float)), np.abs(np.asarray(hi[:n], float)))
        for j in range(n):
            if TRAINING_FACTOR * span[j] > limit[j]:
                limit[j] = TRAINING_FACTOR * span[j]
                source[j] = (f"{TRAINING_FACTOR:g}× the model's training range "
                             f"[{lo[j]:.2f}, {hi[j]:.2f}] rad")
            else:
                source[j] = (f"2π; the model's training range is [{lo[j]:.2f}, {hi[j]:.2f}] "
                             "rad")
    robot = robot_limits(model, n)
    if robot is not None:
        lower, upper, label = robot
        for j in range(n):
            if np.isfinite(lower[j]) and np.isfinite(upper[j]):
                limit[j] = max(abs(lower[j]), abs(upper[j])) + LIMIT_MARGIN_RAD
                source[j] = (f"{label}'s limits [{lower[j]:.2f}, {upper[j]:.2f}] rad + "
                             f"{LIMIT_MARGIN_RAD:g}")
    return JointBounds(limit, tuple(source), names)


def robot_limits(model, n: int):
    """(lower (n,), upper (n,), label) of the joint position limits (rad) of the robot the
    model carries, in its joint order; None without a robot, or if its joints are not `n`
    one-coordinate joints."""
    describe = getattr(model, "robot_description", None)
    description = describe() if callable(describe) else None
    if description is None:
        return None
    try:
        return _limits(description, n)
    except Exception:  # noqa: BLE001 (a robot that does not build has no limits to offer)
        return None


@functools.lru_cache(maxsize=8)
def _limits(description, n: int):
    from ..physics.robot import movable_joint_names  # noqa: PLC0415 (Drake's parser: at start)

    plant, _ = description.build_plant()
    names = tuple(description.joints) or tuple(movable_joint_names(plant))
    if len(names) != n:
        return None
    joints = [plant.GetJointByName(name) for name in names]
    if any(j.num_positions() != 1 for j in joints):
        return None
    lower = np.array([j.position_lower_limits()[0] for j in joints])
    upper = np.array([j.position_upper_limits()[0] for j in joints])
    return lower, upper, f"robot {description.label}"


def robot_joint_names(model) -> tuple[str, ...] | None:
    """The joint names of the robot the model carries, in the model's order; None without."""
    describe = getattr(model, "robot_description", None)
    description = describe() if callable(describe) else None
    if description is None:
        return None
    if description.joints:
        return tuple(description.joints)
    try:
        return _names(description)
    except Exception:  # noqa: BLE001 (as robot_limits)
        return None


@functools.lru_cache(maxsize=8)
def _names(description) -> tuple[str, ...]:
    from ..physics.robot import movable_joint_names  # noqa: PLC0415 (as _limits)

    return tuple(movable_joint_names(description.build_plant()[0]))


# -- message types ---------------------------------------------------------------------------
@functools.cache
def _lcm_fingerprints() -> dict[bytes, str]:
    import drake  # noqa: PLC0415 (the lcm-gen classes; once, on the first bad message)

    found = {}
    for name in dir(drake):
        cls = getattr(drake, name)
        if name.startswith("lcmt_") and hasattr(cls, "_get_packed_fingerprint"):
            found[cls._get_packed_fingerprint()] = f"drake.{name}"
    return found


def lcm_type_found(data: bytes) -> str | None:
    """The ``drake.lcmt_*`` type whose fingerprint `data` starts with, else None."""
    return _lcm_fingerprints().get(bytes(data[:8]))


def lcm_decode_problem(what: str, channel: str, expected: str, key: str,
                       data: bytes) -> tuple[str, str]:
    """(reason, detail) for an LCM message on `channel` that did not decode as `expected`
    (``drake.lcmt_force_torque``): ``wrong_type`` naming the type found, or ``malformed``."""
    found = lcm_type_found(data)
    if found == expected:
        return "malformed", (f"{what} message on LCM channel {channel} is a truncated or "
                             f"corrupt {expected}")
    said = (f"a {found}" if found is not None
            else "of a type ftdrake does not know (its fingerprint is no drake.lcmt_* type)")
    return "wrong_type", (
        f"{what} message on LCM channel {channel} is {said}, expected {expected}. Fix: publish "
        f"{expected} on {channel}, or set {key} to the channel that carries it")


def ros2_type_name(dds_type: str) -> str:
    """``geometry_msgs::msg::dds_::Wrench_`` → ``geometry_msgs/msg/Wrench`` (others as-is)."""
    parts = dds_type.split("::")
    if len(parts) == 4 and parts[2] == "dds_" and parts[3].endswith("_"):
        return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"
    return dds_type


# -- rate --------------------------------------------------------------------------------------
class RateCheck:
    """Measures a stream's rate over its first :data:`RATE_WINDOW_S` of stamps and compares
    it with the configured one (`configured_hz`, named `key` in the warning)."""

    def __init__(self, configured_hz: float, key: str = "chain.sensor.rate_hz",
                 what: str = "F/T messages"):
        self.configured_hz, self.key, self.what = float(configured_hz), key, what
        self.measured_hz: float | None = None
        self._first: float | None = None
        self._count = 0

    def on_sample(self, t: float) -> str | None:
        """One accepted sample stamped `t` (s). Returns the warning once, when the window
        closes with the rate far from the configured one; else None."""
        if self.measured_hz is not None:
            return None
        if self._first is None:
            self._first = t
        self._count += 1
        if t - self._first < RATE_WINDOW_S:
            return None
        self.measured_hz = rate = (self._count - 1) / (t - self._first)
        if abs(rate / self.configured_hz - 1.0) <= RATE_TOLERANCE:
            return None
        return (f"{self.what} arrive at {rate:.0f} Hz (their stamps over the first "
                f"{RATE_WINDOW_S:g} s), but {self.key} is {self.configured_hz:g} Hz: the "
                "chain's filters, bias tracker and detector assume the configured rate. Fix: "
                f"set {self.key}: {rate:.0f} in the live config's chain (or set the driver "
                f"to {self.configured_hz:g} Hz)")


# -- joints against the model ------------------------------------------------------------------
def check_joint_count(model, n: int, key: str, what: str) -> None:
    """ConfigError naming `key` when the model was trained for another number of joints than
    `n`; `what` says what the key should hold."""
    from ..errors import ConfigError  # noqa: PLC0415 (kept out of the module's imports)

    trained = getattr(model, "n_joints_", None)
    if trained is None or int(trained) == int(n):
        return
    robot = robot_joint_names(model)
    names = f": {', '.join(robot)}" if robot and len(robot) == int(trained) else ""
    raise ConfigError(f"{key}: {n} joints, but the model ({type(model).__name__}) was "
                      f"trained for {int(trained)}{names}. Fix: set {key} to {what}")


def joint_names_problem(model, names) -> tuple[str, bool] | None:
    """Compares ros2.joint_names `names` with the joints of the model's robot (when it
    carries one): None when they match (or a name ends with the robot's, a driver's prefix
    such as ``ur_``), else (words, certain): `certain` when the same joints are listed in
    another order (the rows would be wrong), else the names merely differ (a warning)."""
    robot = robot_joint_names(model)
    if robot is None or len(robot) != len(names):
        return None
    if all(name == r or name.endswith(r) for name, r in zip(names, robot, strict=True)):
        return None
    if sorted(names) == sorted(robot):
        return (f"ros2.joint_names lists the joints of the model's robot in another order: "
                f"{list(names)}; the model's order is {list(robot)}. Fix: list them in the "
                "model's order (messages are reordered by name into it)"), True
    return (f"ros2.joint_names {list(names)} are not the joints of the model's robot "
            f"({list(robot)}): check that they are the same joints in the same order"), False
