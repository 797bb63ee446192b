"""The product's configuration: compensator, bias tracker and contact detector."""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
import math

from ..conventions import DEFAULT_ACCELERATION_CUTOFF_HZ
from ..errors import ConfigError
from .checks import finite, non_negative, positive, vector


@dc.dataclass
class CompensatorConfig:
    """How a trained compensator runs in the loop (``CompensatorSystem``)."""

    # Cut-off (Hz) of the tracker on the causal difference of q̇ that estimates q̈ in the loop
    # (a real controller has no q̈ sensor; signals.causal_acceleration); training can use the
    # same estimate. Lower it for a noisy q̇: the white noise it passes grows about in
    # proportion to the cut-off (docs, Derivations).
    acceleration_cutoff_hz: float = DEFAULT_ACCELERATION_CUTOFF_HZ
    # Cut-off (Hz) of the same tracker on the IMU's gyroscope that gives the angular
    # acceleration α of S to a model that takes an IMU (ImuPayloadCompensator): the value its
    # training log's imu_alpha_* columns were derived with (scenario.imu.alpha_cutoff_hz).
    imu_alpha_cutoff_hz: float = 5.0

    def validate(self, where: str = "compensator") -> None:
        positive(self.acceleration_cutoff_hz, f"{where}.acceleration_cutoff_hz")
        positive(self.imu_alpha_cutoff_hz, f"{where}.imu_alpha_cutoff_hz")


#: The payload inertia's prior std (kg·m², per entry of ΔI_So), consistent with the default
#: mass and first-moment priors: (0.5 kg·m)² / 5 kg.
PAYLOAD_INERTIA_PRIOR_STD = 0.05


@dc.dataclass
class PayloadChangeConfig:
    """Telling an unsignalled payload change from a contact (``PayloadChangeMonitor``; with
    ``bias_tracker.track_payload``). See :mod:`ftdrake.runtime.payload_change`."""

    # Off: only a driver's ``payload_changed`` signal makes the tracker re-identify the payload.
    enabled: bool = False
    # The monitor's sample period (s): it keeps one sample of the contact wrench and g_S per
    # period while the detector reports contact, over the last `window_s` seconds.
    sample_period_s: float = 0.02
    window_s: float = 2.0
    # The samples' gravity directions must span this angle (deg) before a decision: without
    # rotation a weight and a steady press look alike.
    min_rotation_deg: float = 10.0
    # A payload change when the payload model (Δm·g_S, Δ(m·c) × g_S) leaves at most this share
    # of the window's weighted sum of squares unexplained ...
    max_unexplained: float = 0.1
    # ... and at most this share of what a wrench constant in S (a press that turns with the
    # tool) leaves.
    max_ratio_to_constant: float = 0.25
    # After a decision the monitor waits this long (s) before it collects again (the tracker
    # re-identifies the payload meanwhile).
    refractory_s: float = 1.0
    # How long the published payload_change flag stays high (s).
    signal_s: float = 0.1

    def validate(self, where: str = "bias_tracker.payload_change") -> "PayloadChangeConfig":
        for name in ("sample_period_s", "window_s", "signal_s"):
            positive(getattr(self, name), f"{where}.{name}")
        non_negative(self.refractory_s, f"{where}.refractory_s")
        if not 0 < self.min_rotation_deg < 180:
            raise ConfigError(f"{where}.min_rotation_deg: {self.min_rotation_deg} not in "
                              f"(0, 180)")
        for name in ("max_unexplained", "max_ratio_to_constant"):
            value = getattr(self, name)
            if not 0 < value < 1:
                raise ConfigError(f"{where}.{name}: {value} not in (0, 1)")
        if self.window_s < 5 * self.sample_period_s:
            raise ConfigError(f"{where}.window_s: {self.window_s} s holds fewer than 5 samples "
                              f"of sample_period_s {self.sample_period_s} s; make it longer")
        return self


@dc.dataclass
class BiasTrackerConfig:
    """Online bias and payload tracking (``OnlineBiasTracker``, between the compensator and
    the detector). See :mod:`ftdrake.runtime.bias_tracker` for the estimator and its guards."""

    # In the chain when a compensator is there. Off: the detector reads the compensator's
    # wrench directly.
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
    # parameters). Off: gravity only (Δm, Δ(m·c) from g − a; the inertia stays at 0), which
    # leaves the payload's offset and inertia terms to bias its centre of mass in motion.
    track_payload_motion: bool = True
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
    # With track_payload: detect a payload change nobody signalled (a grasp the driver does
    # not announce, a tool swapped) and let the tracker re-identify it.
    payload_change: PayloadChangeConfig = dc.field(default_factory=PayloadChangeConfig)

    def validate(self, where: str = "bias_tracker") -> "BiasTrackerConfig":
        for name in ("time_constant_s", "tare_settle_s", "payload_settle_s", "tare_guard_s"):
            positive(getattr(self, name), f"{where}.{name}")
        non_negative(self.tare_jump_window_s, f"{where}.tare_jump_window_s")
        if not (self.rate_bound_sigmas > 0):
            raise ConfigError(f"{where}.rate_bound_sigmas: must be > 0 (inf disables), "
                              f"got {self.rate_bound_sigmas!r}")
        if int(self.hold_samples) < 1:
            raise ConfigError(f"{where}.hold_samples: must be >= 1, got {self.hold_samples!r}")
        vector(self.bias_prior_std, 6, f"{where}.bias_prior_std")
        if self.payload_prior_std is None or len(self.payload_prior_std) not in (4, 10):
            got = 0 if self.payload_prior_std is None else len(self.payload_prior_std)
            raise ConfigError(f"{where}.payload_prior_std: must have 10 entries [Δm, Δ(m·c) "
                              f"(3), ΔI_So (6)] or 4 (Δm, Δ(m·c); the inertia's default), "
                              f"got {got}")
        finite(self.payload_prior_std, f"{where}.payload_prior_std")
        vector(self.initial_bias, 6, f"{where}.initial_bias")
        for name in ("bias_prior_std", "payload_prior_std"):
            if min(getattr(self, name)) <= 0:
                raise ConfigError(f"{where}.{name}: entries must be positive")
        self.payload_change.validate(f"{where}.payload_change")
        return self

    def payload_prior(self) -> list[float]:
        """`payload_prior_std` as 10 entries (a 4-entry list padded with the inertia's
        default)."""
        prior = list(self.payload_prior_std)
        return prior + [PAYLOAD_INERTIA_PRIOR_STD] * (10 - len(prior))


#: The contact detector's tests (DetectorConfig.test); "auto" picks one per model.
DETECTOR_TESTS = ("auto", "norm", "chi2")


@dc.dataclass
class DetectorConfig:
    """Thresholds of the contact detector.

    ``test: "norm"``: contact switches on when ‖F‖ > force_on (N) or ‖T‖ > torque_on (N·m)
    for `debounce_on` consecutive samples, and off when both are below ``release_ratio`` ×
    those thresholds for `debounce_off` samples (hysteresis). With `std_gain` > 0 the
    thresholds grow by ``std_gain · ‖std‖`` of the model's predictive standard deviation.

    ``test: "chi2"``: the 6-D contact wrench whitened by the model's predictive std,
    Σ (wᵢ/σᵢ)², against `chi2_on`, or (`chi2_on` 0) the χ² (6 degrees of freedom) quantile at
    1 − p with p = false_positives_per_hour / (3600 · sample rate): the same budget wherever
    the arm is, the detectable force rising only where the model is unsure. Same debounce;
    off below ``release_ratio² · chi2_on``. Needs a model whose std is that of a reading
    (physics, hybrid, GP).

    ``test: "auto"`` (the default): the χ² test for a model whose std is that of a reading
    *when its threshold is calibrated* — set from held-out free motion (``evaluate-detection``,
    the demo, ``thresholds_for_false_positive_rate(test="auto")``, all of which then record
    the test they chose) or given as `chi2_on` — and the norm test otherwise: for any other
    model (a forest), for an uncalibrated detector (the budget's χ² quantile trusts a std that
    was never checked on held-out motion; the norm defaults are the safer start), and whenever
    `force_on`, `torque_on` or `std_gain` differ from their defaults, since thresholds set by
    hand are meant to be used. The chain resolves it for its model (:meth:`for_model`).
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
    # The false-positive budget (per hour of free motion) that thresholds are calibrated for
    # (ftdrake.offline.thresholds.thresholds_for_false_positive_rate); the detector itself
    # reads only the thresholds.
    false_positives_per_hour: float = 1.0
    # "auto" (chi2 for a model with a std of a reading once calibrated, else norm; above),
    # "norm" (‖F‖, ‖T‖ against force_on, torque_on) or "chi2" (the whitened wrench, above).
    test: str = "auto"
    # The χ² test's threshold on Σ (wᵢ/σᵢ)²; 0: the χ²₆ quantile of the budget.
    chi2_on: float = 0.0

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
        positive(self.false_positives_per_hour, f"{where}.false_positives_per_hour")
        if self.test not in DETECTOR_TESTS:
            raise ConfigError(f"{where}.test: {self.test!r} is not one of {DETECTOR_TESTS}")
        if not (self.chi2_on >= 0 and math.isfinite(self.chi2_on)):
            raise ConfigError(f"{where}.chi2_on: must be >= 0 (0: from the budget), got "
                              f"{self.chi2_on!r}")
        return self

    def sets_norm_thresholds(self) -> bool:
        """Whether force_on, torque_on or std_gain differ from their defaults (the norm
        test's thresholds were set, by hand or by a calibration)."""
        default = DetectorConfig()
        return any(getattr(self, name) != getattr(default, name)
                   for name in ("force_on", "torque_on", "std_gain"))

    def for_model(self, model, *, calibrating: bool = False) -> "DetectorConfig":
        """This config with ``test: "auto"`` resolved for `model` (see the class docstring);
        `calibrating`: the thresholds are about to be set from held-out free motion
        (:func:`~ftdrake.offline.thresholds.thresholds_for_false_positive_rate`). A concrete
        test is returned as it is."""
        if self.test != "auto":
            return self
        chi2 = (model_has_reading_std(model) and not self.sets_norm_thresholds()
                and (calibrating or self.chi2_on > 0))
        return dc.replace(self, test="chi2" if chi2 else "norm")

    def without_model(self) -> "DetectorConfig":
        """This config's test where no model is known (a detector built alone): ``"auto"``
        without a χ² threshold given is the norm test, as for every model; with `chi2_on`
        set it depends on the model, and a ConfigError names :meth:`for_model`."""
        if self.test != "auto":
            return self
        if self.sets_norm_thresholds() or self.chi2_on == 0:
            return dc.replace(self, test="norm")
        raise ConfigError(
            "detector.test 'auto' with chi2_on set picks the test from the compensator's "
            "model: use config.for_model(model), or set detector.test to 'norm' or 'chi2' "
            "(CompensationChain resolves it itself)")


def model_has_reading_std(model) -> bool:
    """Whether `model`'s predictive std is that of a reading — model error and sensor noise,
    as physics, hybrid and GP models give and the χ² test needs (a forest's spread across
    its trees is not one). `model` follows the loop contract
    (:class:`~ftdrake.compensation.contract.LoopModel`)."""
    return bool(model.provides_std and model.std_includes_noise)
