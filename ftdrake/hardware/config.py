"""HardwareConfig: the LCM channels, message types and timeouts of a live robot.

Loadable with ``pydrake.common.yaml.yaml_load_typed(schema=HardwareConfig, ...)``; call
``validate()`` after loading (errors name the field, as ``hardware.<field>: ...``).
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types.
import dataclasses as dc
import math
import warnings

from ..conventions import OUTPUTS, PUBLISHED
from ..errors import ConfigError
from .threads import usable_cpus

#: Joint-state message types understood by :func:`ftdrake.hardware.messages.decode_joint_state`.
JOINT_STATE_TYPES = ("iiwa_status", "panda_status", "robot_state")


def check_outputs(outputs, where: str) -> tuple[str, ...]:
    """The published outputs `outputs` (names of :data:`~ftdrake.conventions.PUBLISHED`)
    as a tuple; ConfigError naming `where` (the ``outputs`` key) for an unknown name, one
    twice or none."""
    if not (isinstance(outputs, (list, tuple)) and outputs
            and all(isinstance(name, str) for name in outputs)):
        raise ConfigError(f"{where}: list the outputs to publish, e.g. [wrench_contact, "
                          f"contact]; they are {', '.join(PUBLISHED)}")
    unknown = [name for name in outputs if name not in PUBLISHED]
    if unknown:
        raise ConfigError(f"{where}: {unknown} not published outputs; choose from "
                          f"{', '.join(PUBLISHED)}")
    if len(set(outputs)) != len(outputs):
        raise ConfigError(f"{where}: {list(outputs)} names an output twice")
    return tuple(outputs)


def check_batch_period(value, max_backlog_s: float, where: str) -> None:
    """ConfigError naming `where`.batch_period_s unless 0 ≤ value < max_backlog_s / 2."""
    if not (isinstance(value, (int, float)) and 0 <= value < 0.5 * max_backlog_s):
        raise ConfigError(f"{where}.batch_period_s: seconds in [0, max_backlog_s / 2) "
                          f"(0: a wake-up per message; 0.002 batches 2 ms), got {value!r}")


def rate_levers(config, section: str) -> str:
    """The settings of a live config's `section` (``lcm``: a :class:`HardwareConfig`;
    ``ros2``: a ``Ros2Config``) that lower serve's CPU per F/T message and that `config`
    does not use yet, in words naming their keys ("" for none): what the overload and the
    little-headroom warning (:mod:`~ftdrake.hardware.overload`) offer as the fix. Only
    settings that lowered it on that transport are offered (docs/results/live.md): on LCM
    fewer outputs, the outputs on a URL of their own, a CPU of serve's own and batches; on
    ROS 2 only batches (fewer outputs and pinning did not lower it there)."""
    levers = []
    if section == "lcm":
        if len(config.outputs) > 2:
            levers.append(f"publish only the outputs read ({section}.outputs, e.g. "
                          "[wrench_contact, contact])")
        if config.output_url in ("", config.lcm_url):
            levers.append(f"publish them on a URL of their own, which serve does not receive "
                          f"({section}.output_url, e.g. another port)")
        if not config.cpu_affinity:
            levers.append(f"give serve a CPU nothing else runs on ({section}.cpu_affinity)")
    if not config.batch_period_s:
        levers.append(f"handle the messages in batches ({section}.batch_period_s, e.g. 0.002, "
                      "adding that much latency)")
    return "; ".join(levers)


def check_yield_io_threads(value, where: str) -> None:
    """ConfigError naming `where`.yield_io_threads unless it is a bool."""
    if not isinstance(value, bool):
        raise ConfigError(f"{where}.yield_io_threads: true or false, got {value!r}")


def check_compiled_path(value, where: str) -> None:
    """ConfigError naming `where`.compiled_path unless it is a bool."""
    if not isinstance(value, bool):
        raise ConfigError(f"{where}.compiled_path: true or false, got {value!r}")


def check_cpu_affinity(value, where: str) -> None:
    """ConfigError naming `where`.cpu_affinity unless it lists distinct CPUs this process may
    run on (empty: the scheduler's choice)."""
    if isinstance(value, (list, tuple)) and not value:
        return
    usable = usable_cpus()
    if not usable:
        raise ConfigError(f"{where}.cpu_affinity: this platform cannot pin a process to CPUs; "
                          "leave it empty")
    if not (isinstance(value, (list, tuple)) and all(
            isinstance(cpu, int) and not isinstance(cpu, bool) for cpu in value)
            and len(set(value)) == len(value) and set(value) <= usable):
        raise ConfigError(f"{where}.cpu_affinity: a list of distinct CPU ids this process may "
                          f"run on ({sorted(usable)}), e.g. [{max(usable)}]; [] leaves it to "
                          f"the scheduler; got {value!r}")


@dc.dataclass
class HardwareConfig:
    """Where a live robot's streams are and how stale they may get.

    Joint state (`joint_state_type`):
      ``iiwa_status``: ``drake.lcmt_iiwa_status`` (q = joint_position_measured, v =
        joint_velocity_estimated, τ = joint_torque_measured).
      ``panda_status``: ``drake.lcmt_panda_status`` (q = joint_position, v = joint_velocity,
        τ = joint_torque).
      ``robot_state``: ``drake.lcmt_robot_state`` carries positions only; velocities arrive
        on a second ``lcmt_robot_state`` channel, `velocity_channel`, whose
        ``joint_position`` field holds v in rad/s with the same ``utime`` as the position
        message it belongs to.
    F/T sensor: ``drake.lcmt_force_torque`` on `ft_channel` (timestamp in µs; see messages).
    Outputs: the chain outputs :data:`ftdrake.conventions.PUBLISHED` (the ROS 2 station
    publishes the same), each on the channel `output_prefix` + its LCM name in
    :data:`~ftdrake.conventions.CHAIN_OUTPUTS` (:meth:`output_channel`; with the default
    prefix ``FT_WRENCH_CONTACT``, ``FT_WRENCH_COMPENSATED``, ``FT_BIAS`` as
    ``lcmt_force_torque``, ``FT_PAYLOAD`` (:func:`encode_payload`), and ``FT_CONTACT_STATE``
    with contact, contact_force, fault, out_of_domain and payload_change
    (``lcmt_drake_signal``, :func:`encode_contact_state`)). `outputs` lists the outputs
    published (default: all): each channel costs a message per F/T sample (on a 2-core
    machine the sends are most of the station's CPU per message, docs/results/live.md), so
    list only those read; the contact state goes out when one of its five values is listed.
    `external_wrench_channel` and
    `contact_channel` are the names of an earlier release, still read for one: the first is
    where ``wrench_compensated`` then goes, the second the contact state's channel.
    Temperature (only for a model trained with the sensor temperature): ``lcmt_drake_signal``
    with one value in °C (:func:`encode_temperature`) on `temperature_channel`; older than
    `temperature_timeout_s` it faults the inputs like a silent sensor.
    IMU (only for a model that takes one): ``lcmt_drake_signal`` with six values
    (:func:`encode_imu`: f_S in m/s², ω_S in rad/s) on `imu_channel`; each F/T sample takes
    the IMU sample stamped nearest to it within `imu_max_skew_s`, none that close faults it.
    Events (optional; for ``chain.bias_tracker``): an ``lcmt_drake_signal``
    (:func:`encode_event`) on `tare_channel` says the driver re-zeroed the sensor, one on
    `payload_channel` that the gripper took or released a payload (needs ``track_payload``).
    The tracker's ``tared`` / ``payload_changed`` input is then high for the next F/T update:
    it re-initialises its bias or payload estimate and averages over ``tare_settle_s`` /
    ``payload_settle_s`` of free motion. With ``track_payload`` the station computes gravity
    at the sensor from the joint state on the model's robot (``JointStateGravity``).
    `compiled_path`: the per-message work (wait, read, checks, chain update, publish) runs
    in one compiled loop on liblcm's own connection whenever the station is in its ordinary
    state, and in Python otherwise, with the same results (:mod:`ftdrake.hardware.lcm.fast`);
    false: always in Python, over the ``lcm`` package's connection. Used only where it
    applies (the summary's ``compiled_path`` says whether and why not); found in numba's
    cache it is loaded before the station serves, else compiled in a process of its own
    while the Python path serves (a first start after an install), then loaded.
    """

    lcm_url: str = "udpm://239.255.76.67:7667?ttl=0"
    # Where the outputs and the status go; "" = lcm_url. Another URL (another port or group)
    # keeps serve from receiving its own outputs: on one multicast group every member gets
    # every message, and each costs serve's receive thread a wake-up (docs/results/live.md).
    output_url: str = ""
    joint_state_channel: str = "IIWA_STATUS"
    joint_state_type: str = "iiwa_status"
    velocity_channel: str = ""  # only for joint_state_type == "robot_state"
    ft_channel: str = "FT_SENSOR"
    output_prefix: str = "FT_"
    outputs: list[str] = dc.field(default_factory=lambda: list(PUBLISHED))
    # Deprecated (see the class docstring): "" unless an older file sets them.
    external_wrench_channel: str = ""
    contact_channel: str = ""
    # The sensor's temperature (lcmt_drake_signal, one value in °C; see messages), for models
    # trained with it; "" when the model needs none.
    temperature_channel: str = ""
    temperature_timeout_s: float = 1.0
    # An IMU at the sensor (lcmt_drake_signal, messages.encode_imu), for a model that takes
    # one; "" when the model needs none. Each F/T sample takes the IMU sample stamped nearest
    # to it within imu_max_skew_s (s); none that close faults that sample.
    imu_channel: str = ""
    imu_max_skew_s: float = 0.002
    # Event signals for the bias tracker (lcmt_drake_signal; messages.encode_event); "" none.
    tare_channel: str = ""
    payload_channel: str = ""
    sensor_timeout_s: float = 0.005
    joint_state_timeout_s: float = 0.02
    n_joints: int = 7
    # Overload (ftdrake.hardware.overload): behind the F/T stream by more than this (s), the
    # station drops the oldest messages and says so; the status channel (output_prefix +
    # STATUS) carries the counts and rates every status_period_s and at each fault change.
    max_backlog_s: float = 0.5
    status_period_s: float = 1.0
    # serve's loop wakes at most once per batch_period_s (s) and then handles every message
    # that arrived: fewer wake-ups (less CPU per message) for up to that much more latency;
    # 0 wakes for each message.
    batch_period_s: float = 0.0
    # LCM's receive thread under SCHED_BATCH (hardware/threads.py): it does not preempt the
    # chain's thread mid-sample; False keeps the default policy.
    yield_io_threads: bool = True
    # CPUs the whole process (every thread) is kept on (hardware/threads.py: the chain's data
    # stays in those cores' caches); [] leaves it to the scheduler.
    cpu_affinity: list[int] = dc.field(default_factory=list)
    # Each F/T sample is paired with the joint state whose stamp is within this (s) of its
    # own, an older one brought forward to the F/T stamp (live_inputs.StreamMonitor); none
    # within it: a fault, never judged. At least the joint stream's period. 0: by arrival
    # only (drivers whose stamps are on different clocks).
    pair_tolerance_s: float = 0.005
    # The per-message work in one compiled loop while the streams are ordinary (see above).
    compiled_path: bool = True

    def output_channel(self, port: str) -> str:
        """The LCM channel of the chain output `port` (a port of
        :data:`~ftdrake.conventions.PUBLISHED`)."""
        channel = OUTPUTS[port].lcm_channel if port in OUTPUTS else None
        if channel is None:
            raise ConfigError(f"hardware: {port!r} is not a published chain output; those are "
                              f"{', '.join(PUBLISHED)}")
        legacy = {"WRENCH_COMPENSATED": self.external_wrench_channel,
                  "CONTACT_STATE": self.contact_channel}.get(channel)
        return legacy or self.output_prefix + channel

    @property
    def status_channel(self) -> str:
        """The station's status channel (:func:`~ftdrake.hardware.messages.encode_status`):
        `output_prefix` + ``STATUS``."""
        return self.output_prefix + "STATUS"

    def output_channels(self) -> dict[str, str]:
        """{LCM channel: the published ports on it (those in `outputs`)}, e.g.
        ``{"FT_CONTACT_STATE": "contact, contact_force, ..."}``."""
        channels = {}
        for port in (p for p in PUBLISHED if p in self.outputs):
            channels.setdefault(self.output_channel(port), []).append(port)
        return {channel: ", ".join(ports) for channel, ports in channels.items()}

    def validate(self, where: str = "hardware") -> "HardwareConfig":
        """Checks every field; ConfigError names the first wrong one (`where` is its path)."""
        if not (isinstance(self.lcm_url, str) and self.lcm_url):
            raise ConfigError(f"{where}.lcm_url: must be a non-empty LCM URL")
        if not isinstance(self.output_url, str):
            raise ConfigError(f"{where}.output_url: an LCM URL, or \"\" for lcm_url's; got "
                              f"{self.output_url!r}")
        check_yield_io_threads(self.yield_io_threads, where)
        check_compiled_path(self.compiled_path, where)
        check_cpu_affinity(self.cpu_affinity, where)
        if self.joint_state_type not in JOINT_STATE_TYPES:
            raise ConfigError(f"{where}.joint_state_type: {self.joint_state_type!r} is not one "
                              f"of {', '.join(JOINT_STATE_TYPES)}")
        if self.joint_state_type == "robot_state" and not self.velocity_channel:
            raise ConfigError(f"{where}.velocity_channel: required when joint_state_type is "
                              "'robot_state' (that message carries positions only)")
        check_outputs(self.outputs, f"{where}.outputs")
        self._check_channels(where)
        for field in ("sensor_timeout_s", "joint_state_timeout_s", "temperature_timeout_s",
                      "max_backlog_s", "status_period_s", "imu_max_skew_s"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and value > 0 and math.isfinite(value)):
                raise ConfigError(f"{where}.{field}: must be a positive number of seconds, "
                                  f"got {value!r}")
        if not (isinstance(self.pair_tolerance_s, (int, float)) and self.pair_tolerance_s >= 0
                and math.isfinite(self.pair_tolerance_s)):
            raise ConfigError(f"{where}.pair_tolerance_s: seconds ≥ 0 (0: pair by arrival), "
                              f"got {self.pair_tolerance_s!r}")
        check_batch_period(self.batch_period_s, self.max_backlog_s, where)
        if not (isinstance(self.n_joints, int) and self.n_joints >= 1):
            raise ConfigError(f"{where}.n_joints: must be a positive integer, got "
                              f"{self.n_joints!r}")
        return self

    def _check_channels(self, where: str) -> None:
        """Every channel named and none twice, the outputs' included; warns on the
        deprecated output fields."""
        for field, now in (("external_wrench_channel", "FT_WRENCH_COMPENSATED"),
                           ("contact_channel", "FT_CONTACT_STATE")):
            if getattr(self, field):
                warnings.warn(f"{where}.{field} is deprecated: the station publishes each "
                              f"output on {where}.output_prefix + its name (e.g. {now}); "
                              f"{getattr(self, field)!r} is still used for this release",
                              FutureWarning, stacklevel=3)
        if not (isinstance(self.output_prefix, str) and self.output_prefix):
            raise ConfigError(f"{where}.output_prefix: must be a non-empty channel prefix, "
                              "e.g. FT_")
        optional = tuple(f for f in ("velocity_channel", "temperature_channel",
                                     "tare_channel", "payload_channel", "imu_channel")
                         if getattr(self, f))
        fields = {field: getattr(self, field)
                  for field in ("joint_state_channel", "ft_channel", *optional)}
        fields.update({f"output_prefix ({ports})": channel
                       for channel, ports in self.output_channels().items()})
        fields["output_prefix (status)"] = self.status_channel
        names = {}
        for field, value in fields.items():
            if not (isinstance(value, str) and value):
                raise ConfigError(f"{where}.{field}: must be a non-empty channel name")
            if value in names:
                raise ConfigError(f"{where}.{field}: channel {value!r} is also "
                                  f"{where}.{names[value]}")
            names[value] = field
