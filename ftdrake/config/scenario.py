"""ScenarioConfig: one simulated scenario, the root of the YAML tree."""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc

from ..errors import ConfigError
from .chain import ChainConfig
from .checks import finite, positive, vector
from .encoders import EncoderConfig
from .imu import ImuConfig
from .plant import CableConfig, ControllerConfig, FrictionConfig, ModelsConfig
from .sensor import SensorConfig
from .task import EventsConfig, TaskConfig, TrajectoryConfig
from .transmission import TransmissionConfig


@dc.dataclass
class ScenarioConfig:
    """One simulated scenario: plant, controller, sensor, cable, trajectory, events, and the
    product's own :class:`ChainConfig` in the loop (``chain``)."""

    time_step: float = 1e-3  # s, discrete plant step
    contact_approximation: str = "sap"
    models: ModelsConfig = dc.field(default_factory=ModelsConfig)
    # Joint configuration the trajectories start from and move around (rad).
    home_q: list[float] = dc.field(
        default_factory=lambda: [0.0, 0.55, 0.0, 1.45, 0.0, 1.14, 0.0]
    )
    controller: ControllerConfig = dc.field(default_factory=ControllerConfig)
    sensor: SensorConfig = dc.field(default_factory=SensorConfig)
    cable: CableConfig = dc.field(default_factory=CableConfig)
    trajectory: TrajectoryConfig = dc.field(default_factory=TrajectoryConfig)
    task: TaskConfig = dc.field(default_factory=TaskConfig)
    # The product in the loop: compensator, bias tracker, detector (its ``sensor`` stream is
    # the simulated sensor's, see chain_config; its ``robot`` defaults to the scenario's arm).
    chain: ChainConfig = dc.field(default_factory=ChainConfig)
    events: EventsConfig = dc.field(default_factory=EventsConfig)
    friction: FrictionConfig = dc.field(default_factory=FrictionConfig)
    transmission: TransmissionConfig = dc.field(default_factory=TransmissionConfig)
    encoders: EncoderConfig = dc.field(default_factory=EncoderConfig)
    # An IMU at the F/T sensor (off by default; see ImuConfig).
    imu: ImuConfig = dc.field(default_factory=ImuConfig)

    def validate(self) -> "ScenarioConfig":
        positive(self.time_step, "scenario.time_step")
        if self.time_step > 0.01:
            raise ConfigError(f"scenario.time_step: {self.time_step} s is too coarse (<= 0.01)")
        if self.contact_approximation not in ("sap", "tamsi", "similar", "lagged"):
            raise ConfigError(
                f"scenario.contact_approximation: unknown {self.contact_approximation!r}"
            )
        vector(self.models.p_WArmBase, 3, "scenario.models.p_WArmBase")
        # One angle per arm joint: the count is known only once the arm's model is parsed,
        # where add_scene checks it; here, what the config alone can say.
        if not self.home_q:
            raise ConfigError("scenario.home_q: must list one angle (rad) per arm joint, got none")
        finite(self.home_q, "scenario.home_q")
        self.controller.validate("scenario.controller")
        self.sensor.validate("scenario.sensor")
        self.cable.validate("scenario.cable")
        self.trajectory.validate("scenario.trajectory")
        self.task.validate("scenario.task")
        if self.trajectory.contact_target not in self.task.surfaces:
            raise ConfigError(
                f"scenario.trajectory.contact_target: {self.trajectory.contact_target!r} is not "
                f"a surface of scenario.task.surfaces {sorted(self.task.surfaces)}"
            )
        self.chain.validate("scenario.chain")
        self.events.validate("scenario.events")
        self.friction.validate("scenario.friction")
        self.transmission.validate("scenario.transmission")
        self.encoders.validate("scenario.encoders")
        self.imu.validate("scenario.imu")
        if self.encoders.enabled and self.encoders.sags() and self.transmission.enabled:
            raise ConfigError("scenario.encoders.sag_stiffness: the compliant transmissions "
                              "(scenario.transmission.enabled) already let the links sag from "
                              "the motors; set the sag stiffnesses to 0 or [] with them")
        rate = self.sensor.spec().rate_hz
        ratio = 1.0 / (rate * self.time_step)
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ConfigError(
                f"scenario.sensor.rate_hz: {rate} Hz must divide the plant rate "
                f"{1 / self.time_step:g} Hz"
            )
        return self


    def chain_config(self) -> ChainConfig:
        """The chain as this scenario runs it: ``chain`` with each unset field of its sensor
        stream read from the simulated sensor (preset, rate, noise, resolution, drift), so
        that the product weighs the noise the simulation makes unless told otherwise."""
        return dc.replace(self.chain, sensor=self.chain.sensor.filled_from(self.sensor))

    def with_chain(self, **sections) -> "ScenarioConfig":
        """A copy with sections of ``chain`` replaced (``with_chain(detector=...)``)."""
        return dc.replace(self, chain=dc.replace(self.chain, **sections))
