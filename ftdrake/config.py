"""Typed configuration of a scenario, loadable and writable as YAML.

Every dataclass here can be read with :func:`load_config` / written with :func:`save_config`
(Drake's ``yaml_load_typed`` / ``yaml_dump_typed``). Errors name the offending field, e.g.
``scenario.sensor.noise_std: must have 6 entries, got 5``.

Units: SI throughout (s, m, kg, N, N·m, rad). Wrench vectors are ``[Fx, Fy, Fz, Tx, Ty, Tz]``.
"""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
import math
from importlib import resources
from pathlib import Path
from typing import Optional

import numpy as np
import yaml as pyyaml
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from .config_transmission import TransmissionConfig
from .errors import ConfigError
from .io import atomic_write_text


# ----------------------------------------------------------------------------------------------
# Sensor presets. Each number's source is in the comment beside it.
# ----------------------------------------------------------------------------------------------
@dc.dataclass(frozen=True)
class SensorSpec:
    """Resolved numbers of a sensor (no Optional fields)."""

    rate_hz: float
    range: tuple  # (6,) N, N·m: saturation limits (symmetric)
    resolution: tuple  # (6,) N, N·m: quantization step
    noise_std: tuple  # (6,) N, N·m: white noise per sample
    bandwidth_hz: float  # first-order low-pass cut-off


SENSOR_PRESETS: dict[str, SensorSpec] = {
    # ATI Gamma, calibration SI-130-10 (ATI F/T catalog, Gamma page): range Fx,Fy ±130 N,
    # Fz ±400 N, Tx,Ty,Tz ±10 N·m; resolution with Net F/T 1/40 N (Fx,Fy), 1/20 N (Fz),
    # 1/800 N·m (T). Net F/T streams up to 7 kHz; we sample at 1 kHz. ATI publishes no noise
    # σ; we assume σ ≈ one resolution step (typical of Net F/T readings at rest).
    "ati_gamma": SensorSpec(
        rate_hz=1000.0,
        range=(130.0, 130.0, 400.0, 10.0, 10.0, 10.0),
        resolution=(1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800),
        noise_std=(1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800),
        bandwidth_hz=400.0,  # assumption: DAQ low-pass set below the 500 Hz Nyquist limit
    ),
    # ATI Mini45, calibration SI-290-10 (ATI F/T catalog, Mini45 page): range Fx,Fy ±290 N,
    # Fz ±580 N, T ±10 N·m; resolution 1/8 N (Fx,Fy), 1/8 N (Fz), 1/376 N·m (T) as listed for
    # Net F/T. Check against your sensor's calibration certificate. Noise σ assumed = resolution.
    "ati_mini45": SensorSpec(
        rate_hz=1000.0,
        range=(290.0, 290.0, 580.0, 10.0, 10.0, 10.0),
        resolution=(1 / 8, 1 / 8, 1 / 8, 1 / 376, 1 / 376, 1 / 376),
        noise_std=(1 / 8, 1 / 8, 1 / 8, 1 / 376, 1 / 376, 1 / 376),
        bandwidth_hz=400.0,
    ),
    # Robotiq FT 300-S (instruction manual): range ±300 N, ±30 N·m; data stream at 100 Hz with
    # Fx·100 and Mx·1000 as 16-bit counts (so 0.01 N, 0.001 N·m steps); signal noise 0.1 N and
    # 0.005 N·m (Robotiq spec sheet).
    "robotiq_ft300": SensorSpec(
        rate_hz=100.0,
        range=(300.0, 300.0, 300.0, 30.0, 30.0, 30.0),
        resolution=(0.01, 0.01, 0.01, 0.001, 0.001, 0.001),
        noise_std=(0.1, 0.1, 0.1, 0.005, 0.005, 0.005),
        bandwidth_hz=40.0,  # assumption: the stream is filtered below its 50 Hz Nyquist limit
    ),
}


@dc.dataclass
class SensorConfig:
    """The noisy F/T sensor. Fields left unset (null) take the preset's value."""

    preset: str = "ati_gamma"
    rate_hz: Optional[float] = None
    range: Optional[list[float]] = None
    resolution: Optional[list[float]] = None
    noise_std: Optional[list[float]] = None
    bandwidth_hz: Optional[float] = None
    # Constant offset of the reading (N, N·m); a real sensor is tared, never perfectly.
    bias: list[float] = dc.field(default_factory=lambda: [0.6, -0.4, 1.2, 0.02, -0.015, 0.01])
    # Thermal drift as a random walk: σ of its increment per √s (N/√s, N·m/√s).
    drift_std: list[float] = dc.field(
        default_factory=lambda: [2e-3, 2e-3, 3e-3, 5e-5, 5e-5, 5e-5]
    )
    # Calibration cross-talk: off-diagonal entries of the calibration error matrix are drawn
    # uniformly in ±crosstalk (relative, torque rows scaled by crosstalk_length_m).
    crosstalk: float = 0.01
    crosstalk_length_m: float = 0.05
    # Calibration gain error per axis, relative (0.01: the axis reads 1 % high); with the
    # cross-talk it makes the sensor's calibration matrix diag(1 + gain_error)·(I + E).
    gain_error: list[float] = dc.field(default_factory=lambda: [0.0] * 6)
    # Mounting error: the frame Sm the sensor measures in is S rotated by these roll, pitch,
    # yaw angles (deg, R_SSm = RollPitchYaw), about So; as a sensor mounted a bolt off or a
    # model's frame a little wrong. The controller's and compensators' models do not know it.
    mounting_rpy_deg: list[float] = dc.field(default_factory=lambda: [1.5, -2.0, 1.0])
    # Temperature (°C): ambient, plus the wrist's warm-up from t = 0, a first-order rise of
    # temperature_rise_c with time constant temperature_time_constant_s.
    temperature_ambient_c: float = 22.0
    temperature_rise_c: float = 10.0
    temperature_time_constant_s: float = 600.0
    # Zero drift per kelvin above temperature_ambient_c (N/K, N·m/K). Order of magnitude from
    # strain-gauge load-cell datasheets, which quote a zero temperature effect of about
    # 0.01–0.05 % of full scale per K; here ≈ 0.03 % of the ati_gamma ranges (130 N, 400 N,
    # 10 N·m), signs mixed. Not a value from an F/T sensor's datasheet.
    temperature_coefficients: list[float] = dc.field(
        default_factory=lambda: [0.039, -0.026, 0.12, 0.003, -0.0025, 0.002]
    )
    # Set False to get an ideal sensor (no noise, bias, drift, cross-talk, quantization, filter,
    # saturation); the sample rate still applies.
    imperfections: bool = True
    seed: int = 0  # noise and drift of this run
    calibration_seed: int = 0  # the cross-talk matrix: a property of the physical sensor

    def spec(self) -> SensorSpec:
        """The resolved numbers: preset values with this config's overrides applied."""
        if self.preset not in SENSOR_PRESETS:
            raise ConfigError(
                f"sensor.preset: unknown preset {self.preset!r}; "
                f"expected one of {sorted(SENSOR_PRESETS)}"
            )
        base = SENSOR_PRESETS[self.preset]
        return SensorSpec(
            rate_hz=base.rate_hz if self.rate_hz is None else float(self.rate_hz),
            range=tuple(base.range if self.range is None else self.range),
            resolution=tuple(base.resolution if self.resolution is None else self.resolution),
            noise_std=tuple(base.noise_std if self.noise_std is None else self.noise_std),
            bandwidth_hz=(
                base.bandwidth_hz if self.bandwidth_hz is None else float(self.bandwidth_hz)
            ),
        )

    def validate(self, where: str = "sensor") -> None:
        spec = self.spec()
        _positive(spec.rate_hz, f"{where}.rate_hz")
        _positive(spec.bandwidth_hz, f"{where}.bandwidth_hz")
        for name, values, allow_zero in (
            ("range", spec.range, False),
            ("resolution", spec.resolution, True),
            ("noise_std", spec.noise_std, True),
            ("bias", self.bias, None),
            ("drift_std", self.drift_std, True),
        ):
            _six(values, f"{where}.{name}")
            if allow_zero is not None:
                for v in values:
                    (_non_negative if allow_zero else _positive)(v, f"{where}.{name}")
        _non_negative(self.crosstalk, f"{where}.crosstalk")
        _six(self.gain_error, f"{where}.gain_error")
        if max(abs(float(v)) for v in self.gain_error) >= 0.2:
            raise ConfigError(f"{where}.gain_error: {self.gain_error} is implausibly large "
                              "(each within ±0.2)")
        if self.crosstalk >= 0.2:
            raise ConfigError(f"{where}.crosstalk: {self.crosstalk} is implausibly large (< 0.2)")
        _vec(self.mounting_rpy_deg, 3, f"{where}.mounting_rpy_deg")
        if max(abs(v) for v in self.mounting_rpy_deg) > 30:
            raise ConfigError(f"{where}.mounting_rpy_deg: {self.mounting_rpy_deg} is not a "
                              "mounting error (each angle within ±30°)")
        _finite([self.temperature_ambient_c, self.temperature_rise_c],
                f"{where}.temperature_ambient_c/temperature_rise_c")
        _positive(self.temperature_time_constant_s, f"{where}.temperature_time_constant_s")
        _six(self.temperature_coefficients, f"{where}.temperature_coefficients")


@dc.dataclass
class CableConfig:
    """A cable/hose from the forearm to the tool: a configuration-dependent force on the tool.

    Tension = stiffness · softplus(distance − rest_length) along the cable, from the tool's
    attachment point towards the anchor on `anchor_body`, plus `weight_n` of hanging cable
    pulling the attachment point down (world −z). Rigid-body models of the tool miss it.
    """

    enabled: bool = True
    anchor_body: str = "link_r"
    p_anchor: list[float] = dc.field(default_factory=lambda: [0.07, 0.0, 0.12])  # m, in anchor
    p_SAttach: list[float] = dc.field(default_factory=lambda: [-0.04, 0.0, 0.04])  # m, in S
    stiffness: float = 25.0  # N/m
    rest_length: float = 0.20  # m
    weight_n: float = 1.2  # N

    def validate(self, where: str = "cable") -> None:
        _vec(self.p_anchor, 3, f"{where}.p_anchor")
        _vec(self.p_SAttach, 3, f"{where}.p_SAttach")
        _non_negative(self.stiffness, f"{where}.stiffness")
        _non_negative(self.rest_length, f"{where}.rest_length")
        _non_negative(self.weight_n, f"{where}.weight_n")


@dc.dataclass
class ControllerConfig:
    """Inverse-dynamics control on a plant with a nominal (imperfect) model of the tool."""

    kp: float = 400.0  # 1/s², per joint
    kd: float = 40.0  # 1/s
    ki: float = 0.0  # 1/s³
    # The controller's estimate of the tool: true mass × (1 + tool_mass_error), CoM shifted.
    tool_mass_error: float = -0.15
    tool_com_error: list[float] = dc.field(default_factory=lambda: [0.01, -0.01, 0.0])  # m, in S

    def validate(self, where: str = "controller") -> None:
        _positive(self.kp, f"{where}.kp")
        _non_negative(self.kd, f"{where}.kd")
        _non_negative(self.ki, f"{where}.ki")
        if not -0.9 < self.tool_mass_error < 2.0:
            raise ConfigError(f"{where}.tool_mass_error: {self.tool_mass_error} not in (-0.9, 2)")
        _vec(self.tool_com_error, 3, f"{where}.tool_com_error")


@dc.dataclass
class FrictionConfig:
    """Joint friction in the simulated arm that the controller's model does not know.

    Per joint i: ``τ_f = viscous_i · v + coulomb_i · tanh(v / velocity_scale)`` (N·m), taken
    off the actuation torque by :class:`ftdrake.systems.friction.JointFriction`. The tanh is
    a smooth sign: the friction is evaluated from the state at the start of each plant step
    (explicitly), so its slope at v = 0, ``viscous + coulomb / velocity_scale``, must stay
    below ~joint inertia / time step (``build_station`` checks it and names the joint).

    Sizes (one entry per arm joint S, L, E, U, R, B, T; this arm's effort limits are
    300, 300, 150, 150, 60, 60, 30 N·m): the Coulomb level is 1 % of each joint's effort
    limit. For scale: the Franka Emika Panda's identified friction (Gaz et al., "Dynamic
    identification of the Franka Emika Panda robot with retrieval of feasible parameters
    using penalty-based optimization", IEEE RA-L 4(4), 2019) is a sigmoid of amplitude
    0.30-1.28 N·m per joint, i.e. 0.6-7 % of its 87 / 12 N·m joint torque limits, with slopes
    5-10 s/rad, i.e. a tanh velocity scale of 0.2-0.4 rad/s. The viscous coefficients (0.5 %
    of the effort limit per rad/s, so viscous ≈ Coulomb at 2 rad/s) are an assumption of the
    same order, not a measured value. This controller's feedback is stiff in acceleration,
    not torque (kp · M̂): the wrist roll resists 0.3 N·m with ~0.3 rad of error, so larger
    values make tracking errors no industrial servo would show. These add to the SDF's joint
    damping (0.5 N·m·s/rad).

    Off by default in the main scenario (the demo's numbers were measured without it); the
    ``learn-feedforward`` experiment turns it on.
    """

    enabled: bool = False
    coulomb: list[float] = dc.field(
        default_factory=lambda: [3.0, 3.0, 1.5, 1.5, 0.6, 0.6, 0.3])  # N·m
    viscous: list[float] = dc.field(
        default_factory=lambda: [1.5, 1.5, 0.75, 0.75, 0.3, 0.3, 0.15])  # N·m·s/rad
    velocity_scale: float = 0.3  # rad/s: tanh(v / velocity_scale) stands in for sign(v)

    def validate(self, where: str = "friction") -> "FrictionConfig":
        if len(self.coulomb) != len(self.viscous):
            raise ConfigError(f"{where}.viscous: must have one entry per joint like "
                              f"{where}.coulomb ({len(self.coulomb)}), got {len(self.viscous)}")
        for name in ("coulomb", "viscous"):
            _finite(getattr(self, name), f"{where}.{name}")
            for v in getattr(self, name):
                _non_negative(v, f"{where}.{name}")
        _positive(self.velocity_scale, f"{where}.velocity_scale")
        return self


TRAJECTORY_KINDS = ("random", "fourier", "reference", "z_rich", "contact", "rehearsal", "study")


@dc.dataclass
class TrajectoryConfig:
    """What the arm does. See :mod:`ftdrake.sim.trajectories` for each kind.

    ``contact`` presses the tool tip into the surface `contact_target` (one of
    ``task.surfaces``); ``rehearsal`` is the same motion stopping `rehearsal_height_m` above
    that surface (contact-free training data that looks like the task)."""

    kind: str = "contact"
    duration_s: float = 14.0
    seed: int = 0
    # Fraction of each joint's speed / acceleration limit the excitation may use.
    speed_fraction: float = 0.3
    acceleration_limit: float = 4.0  # rad/s², every joint
    # Fourier excitation: harmonics of the base frequency.
    base_frequency_hz: float = 0.1
    harmonics: int = 4
    # Contact scenario and its rehearsal. The target is a surface named in task.surfaces.
    contact_target: str = "table"
    # Commanded penetration of the target surface (m); negative: stop that far above it.
    press_depth_m: float = 0.012
    press_duration_s: float = 3.0
    # A rehearsal stops this far above the target surface (m), wherever press_depth_m says.
    rehearsal_height_m: float = 0.03

    def validate(self, where: str = "trajectory") -> None:
        if self.kind not in TRAJECTORY_KINDS:
            raise ConfigError(
                f"{where}.kind: unknown kind {self.kind!r}; expected one of {TRAJECTORY_KINDS}"
            )
        _positive(self.duration_s, f"{where}.duration_s")
        if not 0 < self.speed_fraction <= 1:
            raise ConfigError(f"{where}.speed_fraction: {self.speed_fraction} not in (0, 1]")
        _positive(self.acceleration_limit, f"{where}.acceleration_limit")
        _positive(self.base_frequency_hz, f"{where}.base_frequency_hz")
        if self.harmonics < 1:
            raise ConfigError(f"{where}.harmonics: must be >= 1, got {self.harmonics}")
        # Which names are surfaces is the task's business (ScenarioConfig.validate checks it).
        if not (isinstance(self.contact_target, str) and self.contact_target):
            raise ConfigError(
                f"{where}.contact_target: must name a surface of task.surfaces, "
                f"got {self.contact_target!r}"
            )
        if not -0.2 <= self.press_depth_m <= 0.05:
            raise ConfigError(f"{where}.press_depth_m: {self.press_depth_m} not in [-0.2, 0.05] m")
        _positive(self.press_duration_s, f"{where}.press_duration_s")
        _positive(self.rehearsal_height_m, f"{where}.rehearsal_height_m")
        if self.rehearsal_height_m > 0.2:
            raise ConfigError(
                f"{where}.rehearsal_height_m: {self.rehearsal_height_m} not in (0, 0.2] m"
            )


@dc.dataclass
class TaskConfig:
    """Where the contact task happens, by frame name: the geometry is read from the models.

    A surface frame lies on the surface, at the point the contact scenario presses, with its
    z axis along the outward normal; it is looked up in ``models.environment``. The tool-tip
    frame sits at the point of the tool that touches, with z along the tool axis pointing out
    of the tip; it is looked up in ``models.tool`` and must be on the sensor's tool side.
    Swapping a model for one with the same frame names moves the task with it.
    """

    # Surface name (what trajectory.contact_target selects) → frame in models.environment.
    # A YAML mapping here adds to (or renames the frames of) these defaults.
    surfaces: dict[str, str] = dc.field(
        default_factory=lambda: {"table": "table_top", "wall": "wall_face"}
    )
    tool_tip_frame: str = "tool_tip"

    def validate(self, where: str = "task") -> None:
        if not self.surfaces:
            raise ConfigError(f"{where}.surfaces: name at least one surface frame")
        for name, frame in self.surfaces.items():
            if not (isinstance(frame, str) and frame):
                raise ConfigError(f"{where}.surfaces.{name}: must be a frame name, got {frame!r}")
        if not (isinstance(self.tool_tip_frame, str) and self.tool_tip_frame):
            raise ConfigError(
                f"{where}.tool_tip_frame: must be a frame name, got {self.tool_tip_frame!r}"
            )


@dc.dataclass
class DetectorConfig:
    """Thresholds of the contact detector.

    Contact switches on when ‖F‖ > force_on (N) or ‖T‖ > torque_on (N·m) for `debounce_on`
    consecutive samples, and off when both are below ``release_ratio`` × those thresholds for
    `debounce_off` samples (hysteresis). With `std_gain` > 0 the thresholds grow by
    ``std_gain · ‖std‖`` of the model's predictive standard deviation.
    """

    force_on: float = 2.5
    torque_on: float = 0.25
    release_ratio: float = 0.6
    debounce_on: int = 3
    debounce_off: int = 25
    std_gain: float = 0.0
    # Detection is off for this long after start: the sensor chain and the compensator's
    # acceleration filter settle first (a real detector arms after the sensor is tared).
    arm_after_s: float = 0.05

    def validate(self, where: str = "detector") -> "DetectorConfig":
        for name in ("force_on", "torque_on"):
            value = getattr(self, name)
            if not (value > 0 and math.isfinite(value)):
                raise ConfigError(f"{where}.{name}: must be positive, got {value!r}")
        if not 0 < self.release_ratio <= 1:
            raise ConfigError(f"{where}.release_ratio: {self.release_ratio} not in (0, 1]")
        for name in ("debounce_on", "debounce_off"):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"{where}.{name}: must be >= 1")
        if self.std_gain < 0:
            raise ConfigError(f"{where}.std_gain: must be >= 0, got {self.std_gain}")
        if not self.arm_after_s >= 0:
            raise ConfigError(f"{where}.arm_after_s: must be >= 0, got {self.arm_after_s}")
        return self

    @classmethod
    def from_residuals(cls, residual, margin: float = 1.5, quantile: float = 0.999,
                       **overrides) -> "DetectorConfig":
        """Thresholds from free-motion residuals (N × 6: measured − predicted wrench on
        held-out contact-free data): `margin` × the `quantile` of ‖F‖ and ‖T‖, floored at
        0.5 N and 0.02 N·m. A quantile, not k·RMS: a learned model's residuals are
        heavy-tailed (largest where the motion leaves the training data)."""
        r = np.asarray(residual, dtype=float)
        if r.ndim != 2 or r.shape[1] != 6 or len(r) < 100:
            raise ValueError(f"residual must be N × 6 with N >= 100; got shape {r.shape}")
        force = np.quantile(np.linalg.norm(r[:, :3], axis=1), quantile)
        torque = np.quantile(np.linalg.norm(r[:, 3:], axis=1), quantile)
        return cls(force_on=max(0.5, margin * force), torque_on=max(0.02, margin * torque),
                   **overrides).validate()


@dc.dataclass
class CompensatorConfig:
    """How a trained compensator runs in the loop (``CompensatorSystem``)."""

    # Cut-off (Hz) of the first-order low-pass on the causal difference of q̇ that estimates q̈
    # in the loop (a real controller has no q̈ sensor); training can use the same estimate.
    acceleration_cutoff_hz: float = 25.0

    def validate(self, where: str = "compensator") -> None:
        _positive(self.acceleration_cutoff_hz, f"{where}.acceleration_cutoff_hz")


#: The payload inertia's prior std (kg·m², per entry of ΔI_So), consistent with the default
#: mass and first-moment priors: (0.5 kg·m)² / 5 kg.
PAYLOAD_INERTIA_PRIOR_STD = 0.05


@dc.dataclass
class BiasTrackerConfig:
    """Online bias and payload tracking (``OnlineBiasTracker``, between the compensator and
    the detector). See ``ftdrake/systems/bias_tracker.py`` for the estimator and its guards."""

    # In the station's loop when a compensator is there. Off: the detector reads the
    # compensator's wrench directly (as before the tracker existed).
    enabled: bool = True
    # How a run starts. True: from `initial_bias`, as after τ seconds of tracking (the trained
    # compensator is trusted; only drift is followed). False: as after a tare (the first
    # samples set the bias, so the model's error in the start pose is taken as bias).
    start_settled: bool = True
    # τ (s): memory of the estimator, λ = exp(−period/τ). Long compared with the time a push
    # needs to cross the detector's threshold (≤ 1 s): a ramp is absorbed ~ t²/(2τ).
    time_constant_s: float = 20.0
    # The published bias moves at most k·drift_std/√τ (per axis, from the sensor's drift_std)
    # outside the settle windows; .inf disables the bound. With drift_std 0 the bias then
    # changes only in settle windows (after a tare or a grasp).
    rate_bound_sigmas: float = 3.0
    # Also estimate a rigid payload (Δm, Δ(m·c), ΔI_So: 10 parameters): adds the gravity_S,
    # motion_S and payload_changed inputs and the payload, payload_inertia outputs.
    track_payload: bool = False
    # With track_payload: also feed the tracker S's angular velocity and acceleration
    # (motion_S), so the payload's offset and rotational-inertia terms are modelled (10
    # parameters). Off: gravity only (Δm, Δ(m·c) from g − a; the inertia stays at 0). Exact
    # when the compensator is (tests/test_bias_tracker.py), but in the loop a grasp changes
    # the motion and the compensator's error on it is what remains (README, "The bias tracker").
    track_payload_motion: bool = False
    # Samples (from the signal on) whose update re-initialises the bias (tared) or payload
    # (payload_changed) block; covers the pipeline's one-sample lag.
    hold_samples: int = 3
    # After a tare, the published bias follows the estimate unbounded for this long (s): the
    # estimate averages the free motion since the tare (gain 1/n), so the model's error in
    # the tare pose is averaged out over the poses of this window.
    tare_settle_s: float = 2.0
    # A re-tare is estimated as a jump of the bias when there is history (not at the run's
    # start): the mean of the readings over this long after the hold, less the mean corrected
    # wrench before the tare (s; 0: always reset and settle as above). The estimator keeps its
    # memory: the model's error before and after the tare cancels instead of being taken as
    # bias. The samples of the last `tare_guard_s` before the signal are left out of the
    # "before" mean: a driver's pulse may come a few samples after the new reading.
    tare_jump_window_s: float = 0.05
    tare_guard_s: float = 0.01
    # After a grasp (and at start with payload tracking), bias and payload follow the estimate
    # unbounded for this long (s): rotate the tool within it to identify the CoM.
    payload_settle_s: float = 5.0
    # Prior std (the regulariser): bias N, N·m; payload [Δm kg, Δ(m·c) kg·m (3), ΔI_So kg·m²
    # (6: Ixx Ixy Ixz Iyy Iyz Izz)]. 4 entries (the gravity part) are accepted too: the
    # inertia's then default to PAYLOAD_INERTIA_PRIOR_STD (5 kg at 0.1 m: 0.05 kg·m²).
    bias_prior_std: list[float] = dc.field(
        default_factory=lambda: [20.0, 20.0, 20.0, 2.0, 2.0, 2.0])
    payload_prior_std: list[float] = dc.field(
        default_factory=lambda: [5.0, 0.5, 0.5, 0.5] + [PAYLOAD_INERTIA_PRIOR_STD] * 6)
    # The bias estimate at start (N, N·m), e.g. the compensator's training bias.
    initial_bias: list[float] = dc.field(default_factory=lambda: [0.0] * 6)

    def validate(self, where: str = "bias_tracker") -> "BiasTrackerConfig":
        for name in ("time_constant_s", "tare_settle_s", "payload_settle_s", "tare_guard_s"):
            _positive(getattr(self, name), f"{where}.{name}")
        _non_negative(self.tare_jump_window_s, f"{where}.tare_jump_window_s")
        if not (self.rate_bound_sigmas > 0):
            raise ConfigError(f"{where}.rate_bound_sigmas: must be > 0 (inf disables), "
                              f"got {self.rate_bound_sigmas!r}")
        if int(self.hold_samples) < 1:
            raise ConfigError(f"{where}.hold_samples: must be >= 1, got {self.hold_samples!r}")
        _vec(self.bias_prior_std, 6, f"{where}.bias_prior_std")
        if self.payload_prior_std is None or len(self.payload_prior_std) not in (4, 10):
            got = 0 if self.payload_prior_std is None else len(self.payload_prior_std)
            raise ConfigError(f"{where}.payload_prior_std: must have 10 entries [Δm, Δ(m·c) "
                              f"(3), ΔI_So (6)] or 4 (Δm, Δ(m·c); the inertia's default), "
                              f"got {got}")
        _finite(self.payload_prior_std, f"{where}.payload_prior_std")
        _vec(self.initial_bias, 6, f"{where}.initial_bias")
        for name in ("bias_prior_std", "payload_prior_std"):
            if min(getattr(self, name)) <= 0:
                raise ConfigError(f"{where}.{name}: entries must be positive")
        return self

    def payload_prior(self) -> list[float]:
        """`payload_prior_std` as 10 entries (a 4-entry list padded with the inertia's
        default)."""
        prior = list(self.payload_prior_std)
        return prior + [PAYLOAD_INERTIA_PRIOR_STD] * (10 - len(prior))


@dc.dataclass
class EventsConfig:
    """Things that happen during a run, to test the tracker and the detector. All are off
    (None) by default; times are simulation times (s).

    - **Re-tare**: at `retare_at_s` the sensor driver's zero offset changes, so every later
      reading is shifted by `retare_offset` (N, N·m, in S) — a tare taken in another pose.
      With `retare_signalled` the tracker's ``tared`` input pulses then (the driver knows
      when it tared).
    - **Grasp**: at `grasp_at_s` a point mass `grasp_mass_kg` is added to the tool at
      `grasp_p_SP` (m, from the sensor origin So, in S) — the plant's inertia changes; the
      controller's model and the compensator do not know. With `grasp_signalled` the
      tracker's ``payload_changed`` input pulses (the gripper's command is known).
    - **Push**: from `push_at_s` a force at the tool tip grows linearly over `push_ramp_s` to
      `push_force_W` (N, world frame), stays for `push_hold_s`, then stops. It is applied as
      an external force (not contact), and it is added to the log's ``external_*`` columns
      (at the sensor, in S) like a contact would be.
    """

    retare_at_s: Optional[float] = None
    # ‖F‖ 5.0 N, ‖T‖ 0.20 N·m (the "5 N / 0.2 N·m")
    retare_offset: list[float] = dc.field(
        default_factory=lambda: [2.9, -2.9, 2.9, 0.116, -0.116, 0.116])
    retare_signalled: bool = True
    grasp_at_s: Optional[float] = None
    grasp_mass_kg: float = 0.5
    grasp_p_SP: list[float] = dc.field(default_factory=lambda: [0.0, 0.02, 0.12])
    grasp_signalled: bool = True
    push_at_s: Optional[float] = None
    push_ramp_s: float = 5.0
    push_hold_s: float = 1.0
    push_force_W: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, -5.0])
    # How long the tared / payload_changed signals stay high (s): a driver's tare or a
    # gripper's close takes a while, and the tracker re-initialises while the signal is high
    # (so the grasp's transient, while the controller catches the new weight, is not contact).
    signal_s: float = 0.25

    def validate(self, where: str = "events") -> "EventsConfig":
        for name in ("retare_at_s", "grasp_at_s", "push_at_s"):
            value = getattr(self, name)
            if value is not None:
                _non_negative(value, f"{where}.{name}")
        _six(self.retare_offset, f"{where}.retare_offset")
        _positive(self.grasp_mass_kg, f"{where}.grasp_mass_kg")
        _vec(self.grasp_p_SP, 3, f"{where}.grasp_p_SP")
        _positive(self.push_ramp_s, f"{where}.push_ramp_s")
        _non_negative(self.push_hold_s, f"{where}.push_hold_s")
        _vec(self.push_force_W, 3, f"{where}.push_force_W")
        _positive(self.signal_s, f"{where}.signal_s")
        return self

    @property
    def any(self) -> bool:
        return any(t is not None for t in (self.retare_at_s, self.grasp_at_s, self.push_at_s))


@dc.dataclass
class ModelsConfig:
    """Where the models come from. package://ftdrake/ resolves to the shipped models/."""

    arm: str = "package://ftdrake/sda10d_arm.sdf"
    tool: str = "package://ftdrake/ft_sensor_tool.sdf"
    environment: str = "package://ftdrake/environment.sdf"
    arm_base_frame: str = "arm_base"
    flange_frame: str = "flange"  # on the arm; the tool's mount frame is welded to it
    tool_mount_frame: str = "ft_sensor"
    sensor_joint: str = "ft_sensor_weld"
    p_WArmBase: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 0.95])  # m
    # Extra package.xml files for a user's own models.
    package_xmls: list[str] = dc.field(default_factory=list)


@dc.dataclass
class ScenarioConfig:
    """One simulated scenario: plant, controller, sensor, cable, trajectory and logging."""

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
    compensator: CompensatorConfig = dc.field(default_factory=CompensatorConfig)
    detector: DetectorConfig = dc.field(default_factory=DetectorConfig)
    bias_tracker: BiasTrackerConfig = dc.field(default_factory=BiasTrackerConfig)
    events: EventsConfig = dc.field(default_factory=EventsConfig)
    friction: FrictionConfig = dc.field(default_factory=FrictionConfig)
    transmission: TransmissionConfig = dc.field(default_factory=TransmissionConfig)

    def validate(self) -> "ScenarioConfig":
        _positive(self.time_step, "scenario.time_step")
        if self.time_step > 0.01:
            raise ConfigError(f"scenario.time_step: {self.time_step} s is too coarse (<= 0.01)")
        if self.contact_approximation not in ("sap", "tamsi", "similar", "lagged"):
            raise ConfigError(
                f"scenario.contact_approximation: unknown {self.contact_approximation!r}"
            )
        _vec(self.models.p_WArmBase, 3, "scenario.models.p_WArmBase")
        # One angle per arm joint: the count is known only once the arm's model is parsed,
        # where add_scene checks it; here, what the config alone can say.
        if not self.home_q:
            raise ConfigError("scenario.home_q: must list one angle (rad) per arm joint, got none")
        _finite(self.home_q, "scenario.home_q")
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
        self.compensator.validate("scenario.compensator")
        self.detector.validate("scenario.detector")
        self.bias_tracker.validate("scenario.bias_tracker")
        self.events.validate("scenario.events")
        self.friction.validate("scenario.friction")
        self.transmission.validate("scenario.transmission")
        rate = self.sensor.spec().rate_hz
        ratio = 1.0 / (rate * self.time_step)
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ConfigError(
                f"scenario.sensor.rate_hz: {rate} Hz must divide the plant rate "
                f"{1 / self.time_step:g} Hz"
            )
        return self


# ----------------------------------------------------------------------------------------------
# YAML in and out.
# ----------------------------------------------------------------------------------------------
def default_scenario_path() -> Path:
    """The scenario file shipped with ftdrake (the defaults, written out)."""
    return Path(str(resources.files("ftdrake") / "scenarios" / "default.yaml"))


def load_config(path: "str | Path | None" = None, schema=ScenarioConfig):
    """Reads a YAML file into `schema` and validates it. None → the shipped default."""
    path = Path(path) if path is not None else default_scenario_path()
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(f"cannot read config {path}: {e.strerror}") from None
    return parse_config(text, schema, source=str(path))


def parse_config(text: str, schema=ScenarioConfig, source: str = "<string>"):
    """Parses YAML text into `schema`, naming the bad field on error."""
    try:
        data = pyyaml.safe_load(text)
    except pyyaml.YAMLError as e:
        raise ConfigError(f"{source}: malformed YAML: {e}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of fields, got {type(data).__name__}")
    _check_fields(data, schema, "scenario" if schema is ScenarioConfig else schema.__name__)
    try:
        config = yaml_load_typed(schema=schema, data=text)
    except (RuntimeError, ValueError, TypeError) as e:
        raise ConfigError(f"{source}: {e}") from None
    if hasattr(config, "validate"):
        config.validate()
    return config


def save_config(config, path: "str | Path") -> None:
    """Writes `config` as YAML, atomically."""
    atomic_write_text(Path(path), dump_config(config))


def dump_config(config) -> str:
    return yaml_dump_typed(config)


def _check_fields(data: dict, schema, where: str) -> None:
    """Names unknown fields with their full path (Drake's loader names only the leaf)."""
    fields = {f.name: f for f in dc.fields(schema)}
    for key, value in data.items():
        if key not in fields:
            raise ConfigError(f"{where}.{key}: unknown field; known fields: {sorted(fields)}")
        sub = fields[key].default_factory if fields[key].default_factory is not dc.MISSING else None
        if sub is not None and dc.is_dataclass(sub) and isinstance(value, dict):
            _check_fields(value, sub, f"{where}.{key}")


def _positive(v, name):
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
        raise ConfigError(f"{name}: must be a positive number, got {v!r}")


def _non_negative(v, name):
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
        raise ConfigError(f"{name}: must be a non-negative number, got {v!r}")


def _vec(values, n, name):
    if values is None or len(values) != n:
        got = 0 if values is None else len(values)
        raise ConfigError(f"{name}: must have {n} entries, got {got}")
    _finite(values, name)


def _finite(values, name):
    for v in values:
        if not (isinstance(v, (int, float)) and math.isfinite(v)):
            raise ConfigError(f"{name}: entries must be finite numbers, got {v!r}")


def _six(values, name):
    _vec(values, 6, name)
