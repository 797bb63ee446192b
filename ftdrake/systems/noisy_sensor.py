"""NoisyForceTorqueSensor: a real sensor's imperfections added to an ideal wrench.

Same frames, units and signs as :mod:`ftdrake.systems.ft_sensor` (wrench ``[F; T]`` in N and
N·m about So, expressed in S, the load the tool side applies to the sensor). What it adds, each
set by :class:`~ftdrake.config.SensorConfig`: sampling and a hold, noise, bias drift,
temperature drift, gain and cross-talk, a mounting rotation, saturation and a low-pass; and
a delay of the wrench stream behind the joint states (``stream_delay_s``).
"""

from __future__ import annotations

import functools

import numba
import numpy as np
from pydrake.math import RollPitchYaw
from pydrake.systems.framework import LeafSystem

from ..config import SensorConfig
from ..errors import ConfigError

#: No vibration: nothing is added to the sample (NoisyForceTorqueSensor without it).
_NO_SHAKE = np.zeros(6)


class NoisyForceTorqueSensor(LeafSystem):
    """Adds a real sensor's imperfections to an ideal wrench, sampled at ``rate_hz``.

    Input ports:
      wrench_ideal (6): ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m, sensor frame S (the model's).
      joint_state (2n; only with vibration, ``config.vibrates``): the arm's ``[q; v]``, rad,
        rad/s (the plant's state port of the arm).
      joint_acceleration (n; only with vibration): the arm's v̇, rad/s² (the plant's
        generalized acceleration port of the arm).
    Output ports:
      wrench_measured (6): in the frame Sm the sensor really measures in (S rotated by the
        mounting error, ``config.mounting_rpy_deg``), N, N·m; held between samples.
      saturated (1): 1.0 while any axis is at its range limit.
      temperature (1): the sensor's temperature, °C, held between samples.
    State (discrete, updated every 1/rate_hz s): low-pass filter and drift (12) with the
      sample count (1); the held reading (6); the saturation flag (1); the temperature (1);
      with a stream delay of k samples, the k readings not yet published (6k).

    Per sample, in this order: the mounting rotation ``w_Sm = [R_SmS f; R_SmS τ]`` (about So)
    and the calibration error ``G·C·w_Sm`` (cross-talk C, per-axis gain error G);
    first-order low-pass at ``bandwidth_hz``; + constant bias + thermal zero drift
    ``k·(T − T_ambient)`` + random-walk drift + white noise; saturation at ``±range``;
    quantization to ``resolution``; then, with ``stream_delay_s`` = k samples, the reading
    is published k samples late (the wrench stream lags the joint states by k/rate_hz s, as
    a real F/T driver's latency does; the first reading is repeated until the delayed ones
    arrive; applied with ``imperfections`` off too, it is the stream's, not the sensor's).
    The temperature is
    ``T(t) = T_ambient + ΔT·(1 − exp(−t/τ))`` (the wrist warming up from t = 0). Noise is a
    pure function of (seed, sample index), so a run is reproducible from its seed and
    contexts can be cloned freely.

    Vibration (``vibration_per_speed``/``vibration_per_acceleration`` not all zero): beside
    the white noise each axis gets ``σ_vib·n`` with ``σ_vib = a·‖v‖ + b·‖v̇‖`` at the sample
    (n standard normal, from a stream of its own: the other draws are those of the same run
    without vibration). `n_joints` (n) is then required: the size of the joint inputs.
    """

    _BLOCK = 4096  # samples of noise drawn at once

    def __init__(self, config: SensorConfig, n_joints: int | None = None):
        super().__init__()
        config.validate()  # the system is built on its own too, from a SensorConfig alone
        self.config = config
        spec = config.spec()
        self.period = 1.0 / spec.rate_hz
        self._on = bool(config.imperfections)
        self._range = np.asarray(spec.range, dtype=float)
        self._resolution = np.asarray(spec.resolution, dtype=float)
        self._noise_std = np.asarray(spec.noise_std, dtype=float)
        self._bias = np.asarray(config.bias, dtype=float)
        self._drift_step = np.asarray(config.drift_std, dtype=float) * np.sqrt(self.period)
        self._alpha = 1.0 - np.exp(-2 * np.pi * spec.bandwidth_hz * self.period)
        self.crosstalk_matrix = crosstalk_matrix(
            config.crosstalk, config.crosstalk_length_m, config.calibration_seed
        )
        #: The calibration's per-axis gain error, diag(1 + gain_error).
        self.gain_matrix = np.diag(1.0 + np.asarray(config.gain_error, dtype=float))
        #: R_SSm: the frame Sm the sensor measures in, in the model's S.
        self.mounting_rotation = mounting_rotation(config.mounting_rpy_deg)
        rotate = np.kron(np.eye(2), self.mounting_rotation.T)  # w_Sm = rotate · w_S
        #: What the sensor does to a wrench in S, linearly: the mounting rotation, then the
        #: cross-talk and the gain error (W_Sm = calibration_matrix · W_S before the bias).
        self.calibration_matrix = self.gain_matrix @ self.crosstalk_matrix @ rotate
        self._temperature_coefficients = np.asarray(config.temperature_coefficients, float)
        self._temperature = (float(config.temperature_ambient_c),
                             float(config.temperature_rise_c),
                             float(config.temperature_time_constant_s))
        self._input = self.DeclareVectorInputPort("wrench_ideal", 6)
        self._vibration = None
        if config.vibrates and self._on:
            self._declare_vibration(config, n_joints)
        # Three state groups so the outputs are plain state ports (no Python call per read).
        self._internal = self.DeclareDiscreteState(13)  # filter (6), drift (6), sample count
        self._reading = self.DeclareDiscreteState(6)
        self._saturated = self.DeclareDiscreteState(1)
        self._temperature_state = self.DeclareDiscreteState([self._temperature[0]])
        #: Samples the reading is published late (SensorConfig.stream_delay_s, rounded).
        self.delay_samples = round(float(config.stream_delay_s) * spec.rate_hz)
        self._delayed = (self.DeclareDiscreteState(6 * self.delay_samples)
                         if self.delay_samples else None)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._sample)
        self.DeclareStateOutputPort("wrench_measured", self._reading)
        self.DeclareStateOutputPort("saturated", self._saturated)
        self.DeclareStateOutputPort("temperature", self._temperature_state)
        # All constants in one array, so the compiled update takes few arguments (each costs
        # time at every call): rows 0–5 the cross-talk matrix, then per axis bias, noise σ,
        # drift step, range, resolution and the filter's α; the temperature coefficients;
        # [ambient, rise, time constant, period, 0, 0].
        self._constants = np.vstack([
            self.calibration_matrix, self._bias, self._noise_std, self._drift_step, self._range,
            self._resolution, np.full(6, self._alpha), self._temperature_coefficients,
            [*self._temperature, self.period, 0.0, 0.0],
        ])
        # (block index, its draws): the last noise block this sensor used.
        self._noise = (-1, np.zeros((self._BLOCK, 12)))

    def _declare_vibration(self, config: SensorConfig, n_joints) -> None:
        if n_joints is None or int(n_joints) < 1:
            raise ConfigError(
                "sensor.vibration_per_speed/vibration_per_acceleration: a vibrating sensor "
                "reads the arm's motion; build NoisyForceTorqueSensor(config, n_joints=n) and "
                "connect its joint_state and joint_acceleration inputs (build_station does)")
        n = self.n_joints = int(n_joints)
        self._state_port = self.DeclareVectorInputPort("joint_state", 2 * n)
        self._accel_port = self.DeclareVectorInputPort("joint_acceleration", n)
        self._per_speed = np.asarray(config.vibration_per_speed, dtype=float)
        self._per_acceleration = np.asarray(config.vibration_per_acceleration, dtype=float)
        self._vibration = (-1, np.zeros((self._BLOCK, 6)))  # (block index, its draws)
        self._shake = np.zeros(6)

    def vibration_std(self, speed, acceleration) -> np.ndarray:
        """σ_vib (N, N·m; (..., 6)) at joint speed ‖v‖ (rad/s) and acceleration ‖v̇‖ (rad/s²),
        arrays of the same shape (zeros without vibration)."""
        if self._vibration is None:
            return np.zeros((*np.shape(speed), 6))
        return (np.multiply.outer(speed, self._per_speed)
                + np.multiply.outer(acceleration, self._per_acceleration))

    def _vibration_sample(self, context, count: int) -> np.ndarray:
        """This sample's vibration (6): σ_vib at the arm's motion times its own draws."""
        block, draws = self._vibration
        if count // self._BLOCK != block:
            block = count // self._BLOCK
            draws = _noise_block(self.config.seed, block, self._BLOCK, stream=1, width=6)
            self._vibration = (block, draws)
        v = self._state_port.Eval(context)[self.n_joints:]
        sigma = self.vibration_std(np.linalg.norm(v),
                                   np.linalg.norm(self._accel_port.Eval(context)))
        np.multiply(sigma, draws[count % self._BLOCK], out=self._shake)
        return self._shake

    # -- what the sensor does to a wrench without randomness ---------------------------------
    def get_input_port_wrench_ideal(self):
        return self.GetInputPort("wrench_ideal")

    def get_input_port_joint_state(self):
        return self.GetInputPort("joint_state")

    def get_input_port_joint_acceleration(self):
        return self.GetInputPort("joint_acceleration")

    def get_output_port_wrench_measured(self):
        return self.GetOutputPort("wrench_measured")

    def get_output_port_saturated(self):
        return self.GetOutputPort("saturated")

    def get_output_port_temperature(self):
        return self.GetOutputPort("temperature")

    def temperature(self, t) -> np.ndarray:
        """The sensor's temperature (°C) at times `t` (s): ``T_a + ΔT·(1 − exp(−t/τ))``."""
        ambient, rise, tau = self._temperature
        return ambient + rise * (1.0 - np.exp(-np.asarray(t, dtype=float) / tau))

    def deterministic_reading(self, wrench, t=None) -> np.ndarray:
        """``C·R·w + bias`` (+ the thermal zero drift at times `t`, s, if given) for (N, 6) or
        (6,) wrenches in S: the reading without noise, random-walk drift, filter and
        quantization, in the frame Sm the sensor measures in."""
        w = np.asarray(wrench, dtype=float)
        if not self._on:
            return w.copy()
        reading = w @ self.calibration_matrix.T + self._bias
        if t is not None:
            rise = self.temperature(t) - self._temperature[0]
            reading = reading + np.multiply.outer(rise, self._temperature_coefficients)
        return reading

    # -- the discrete update -----------------------------------------------------------------
    def _sample(self, context, discrete_state):
        # Runs every sample (1 kHz by default), so it makes few Python calls: the update
        # buffer starts as a copy of the current state and is updated in place.
        internal = discrete_state.get_mutable_value(self._internal)
        reading = discrete_state.get_mutable_value(self._reading)
        saturated = discrete_state.get_mutable_value(self._saturated)
        temperature = discrete_state.get_mutable_value(self._temperature_state)
        w = self._input.Eval(context)
        first = internal[12] == 0
        temperature[0] = _temperature_at(internal[12], self._constants[13])
        if not self._on:
            _ideal_sample(internal, w, reading, saturated)
        else:
            block, noise = self._noise
            shake = (_NO_SHAKE if self._vibration is None
                     else self._vibration_sample(context, int(internal[12])))
            if not _imperfect_sample(internal, w, self._constants, block, noise, shake,
                                     reading, saturated):
                # This sample's draws are in another block (every 4096 samples, or a new run).
                block = int(internal[12]) // self._BLOCK
                self._noise = (block, _noise_block(self.config.seed, block, self._BLOCK))
                _imperfect_sample(internal, w, self._constants, *self._noise, shake, reading,
                                  saturated)
        if self._delayed is not None:
            _delay(discrete_state.get_mutable_value(self._delayed), reading, first)


@numba.njit(cache=True)
def _imperfect_sample(internal, w, constants, block, noise_block, shake, reading, saturated):
    """One sample of the imperfect sensor, written in place; False (nothing written) if this
    sample's draws are not in `noise_block`.

    `internal` is [filter (6), drift (6), sample count]; `constants` as built in
    NoisyForceTorqueSensor.__init__; `noise_block` is block number `block` of the draws
    (12 per sample: white noise then drift increments); `shake` (6) the vibration added to
    the sample (an axis with 0 gets nothing added: without vibration the sum is as before).
    """
    count = int(internal[12])
    size = noise_block.shape[0]
    if count // size != block:
        return False
    C, axis = constants[:6], constants[6:]
    alpha = axis[5, 0]
    noise = noise_block[count % size]
    first = internal[12] == 0
    saturated[0] = 0.0
    warm = _temperature_at(internal[12], constants[13]) - constants[13, 0]
    for i in range(6):
        wi = 0.0
        for j in range(6):
            wi += C[i, j] * w[j]
        filtered = wi if first else internal[i] + alpha * (wi - internal[i])
        drift = internal[6 + i] + axis[2, i] * noise[6 + i]
        value = (filtered + axis[0, i] + axis[6, i] * warm + drift
                 + axis[1, i] * noise[i])
        if shake[i] != 0.0:
            value += shake[i]
        limit = axis[3, i]
        if abs(value) >= limit:
            saturated[0] = 1.0
            value = limit if value > 0 else -limit
        resolution = axis[4, i]
        if resolution > 0:
            value = np.round(value / resolution) * resolution
        internal[i], internal[6 + i], reading[i] = filtered, drift, value
    internal[12] += 1
    return True


@numba.njit(cache=True)
def _delay(queue, reading, first):
    """A FIFO of k readings (`queue`, 6k, oldest first): `reading` (6) goes in, the oldest
    comes out into `reading`; on the `first` sample the queue is filled with it."""
    n = queue.shape[0]
    if first:
        for i in range(n):
            queue[i] = reading[i % 6]
    for i in range(6):
        fresh = reading[i]
        reading[i] = queue[i]
        for j in range(i, n - 6, 6):
            queue[j] = queue[j + 6]
        queue[n - 6 + i] = fresh


@numba.njit(cache=True)
def _temperature_at(count, row):
    """Temperature (°C) at sample `count`; row = [ambient, rise, time constant, period, ...]."""
    return row[0] + row[1] * (1.0 - np.exp(-count * row[3] / row[2]))


@numba.njit(cache=True)
def _ideal_sample(internal, w, reading, saturated):
    """Sample-and-hold only (imperfections off)."""
    for i in range(6):
        internal[i] = w[i]
        reading[i] = w[i]
    saturated[0] = 0.0
    internal[12] += 1


@functools.lru_cache(maxsize=4)
def _noise_block(seed: int, block: int, size: int, stream: int = 0,
                 width: int = 12) -> np.ndarray:
    """Standard normal draws (size × width) for samples [block·size, (block+1)·size):
    stream 0 the white noise and drift increments (12 per sample), stream 1 the vibration's
    (6)."""
    key = [seed, block] if stream == 0 else [seed, block, stream]
    return np.random.default_rng(key).standard_normal((size, width))


def mounting_rotation(rpy_deg) -> np.ndarray:
    """R_SSm of a mounting error given as roll, pitch, yaw in degrees (Drake's RollPitchYaw:
    R = Rz(yaw)·Ry(pitch)·Rx(roll))."""
    return RollPitchYaw(np.radians(np.asarray(rpy_deg, dtype=float))).ToRotationMatrix().matrix()


def crosstalk_matrix(magnitude: float, length_m: float, seed: int) -> np.ndarray:
    """Calibration matrix ``C = I + E``: small off-diagonal coupling between axes.

    Entries of E are uniform in ±magnitude (dimensionless between like axes); a force leaking
    into a torque channel is scaled by `length_m` (N·m per N), a torque into a force channel by
    1/length_m. Drawn from `seed`, so a sensor's calibration error is fixed per seed.
    """
    rng = np.random.default_rng([seed, 7919])
    E = rng.uniform(-magnitude, magnitude, size=(6, 6))
    np.fill_diagonal(E, 0.0)
    E[3:, :3] *= length_m
    E[:3, 3:] /= length_m
    return np.eye(6) + E
