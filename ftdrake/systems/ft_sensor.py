"""Force/torque sensors as Drake systems.

Convention (used everywhere in ftdrake; tested in tests/test_sensor_physics.py):

* A wrench is ``[Fx, Fy, Fz, Tx, Ty, Tz]`` in N and N·m (force first, as ROS WrenchStamped and
  the study). Drake's ``SpatialForce`` is ``[torque; force]``; the conversion happens in
  :func:`wrench_from_spatial_force` / :func:`spatial_force_from_wrench` (and, compiled for the
  1 kHz loop, in ``_negated_wrench``, tested equal to them).
* The sensor reports the load that the **tool side applies to the sensor** (ATI's convention),
  about the origin So of the sensor frame S, expressed in S. S is the sensor weld joint's child
  frame ``Jc``; the tool is the weld's child side.
* Drake's reaction-forces port gives ``F_CJc_Jc``: the force the joint applies to the child body C
  at Jc, expressed in Jc. By Newton's third law the tool applies ``-F_CJc_Jc`` to the sensor, so
  the sensor reads ``wrench = -F_CJc_Jc`` (same point, same frame).
* Consequence, at rest: the reading is the tool's weight ``m·g`` expressed in S (pointing down in
  the world) and the torque ``p_SoScm × m·g`` about So.
"""

from __future__ import annotations

import functools

import numba
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RollPitchYaw
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.tree import WeldJoint
from pydrake.systems.framework import BasicVector, LeafSystem

from ..config import SensorConfig


def wrench_from_spatial_force(F: SpatialForce) -> np.ndarray:
    """Drake ``[τ; f]`` → ftdrake ``[Fx, Fy, Fz, Tx, Ty, Tz]``."""
    return np.concatenate([F.translational(), F.rotational()])


def spatial_force_from_wrench(w) -> SpatialForce:
    """ftdrake ``[Fx, Fy, Fz, Tx, Ty, Tz]`` → Drake ``SpatialForce(τ, f)``."""
    w = np.asarray(w, dtype=float)
    return SpatialForce(tau=w[3:], f=w[:3])


class ForceTorqueSensor(LeafSystem):
    """Ideal 6-axis F/T sensor at a weld joint of any MultibodyPlant.

    Input ports:
      reaction_forces (abstract, list of SpatialForce): connect the plant's
        ``get_reaction_forces_output_port()``.
    Output ports:
      wrench (6): ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m: the load the child (tool) side applies to
        the sensor, about the weld's child-frame origin So, expressed in that frame S.

    With a discrete plant, the reaction port is sampled: it reads all zeros until the plant has
    taken its first step, so this sensor reads zero at t = 0.
    """

    def __init__(self, plant, joint):
        super().__init__()
        if not isinstance(joint, WeldJoint):
            raise TypeError(
                f"ForceTorqueSensor needs a weld joint; {joint.name()!r} is a "
                f"{joint.type_name()} joint"
            )
        if plant.get_joint(joint.index()).name() != joint.name():
            raise ValueError(f"joint {joint.name()!r} does not belong to this plant")
        self._joint_index = int(joint.index())
        self._num_joints = plant.num_joints()
        self._reaction_forces = self.DeclareAbstractInputPort(
            "reaction_forces", AbstractValue.Make([SpatialForce()] * self._num_joints)
        )
        self.DeclareVectorOutputPort(
            "wrench", 6, self._calc_wrench,
            prerequisites_of_calc={self.input_port_ticket(self._reaction_forces.get_index())},
        )

    def get_input_port_reaction_forces(self):
        return self.GetInputPort("reaction_forces")

    def get_output_port_wrench(self):
        return self.GetOutputPort("wrench")

    def _calc_wrench(self, context, output: BasicVector):
        # Runs every plant step, so it makes as few Python calls as it can.
        forces = self._reaction_forces.Eval(context)
        if len(forces) != self._num_joints:
            raise ValueError(
                f"reaction_forces has {len(forces)} entries; the plant has {self._num_joints} "
                "joints (is the port connected to the right plant?)"
            )
        _negated_wrench(forces[self._joint_index].get_coeffs(), output.get_mutable_value())


@numba.njit(cache=True)
def _negated_wrench(tau_f, out):
    """``out = -[f; τ]`` from Drake's spatial-force coefficients ``[τ; f]``."""
    for i in range(3):
        out[i] = -tau_f[3 + i]
        out[3 + i] = -tau_f[i]


class NoisyForceTorqueSensor(LeafSystem):
    """Adds a real sensor's imperfections to an ideal wrench, sampled at ``rate_hz``.

    Input ports:
      wrench_ideal (6): ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m, sensor frame S (the model's).
    Output ports:
      wrench_measured (6): in the frame Sm the sensor really measures in (S rotated by the
        mounting error, ``config.mounting_rpy_deg``), N, N·m; held between samples.
      saturated (1): 1.0 while any axis is at its range limit.
      temperature (1): the sensor's temperature, °C, held between samples.
    State (discrete, updated every 1/rate_hz s): low-pass filter and drift (12) with the
      sample count (1); the held reading (6); the saturation flag (1); the temperature (1).

    Per sample, in this order: the mounting rotation ``w_Sm = [R_SmS f; R_SmS τ]`` (about So)
    and the calibration error ``G·C·w_Sm`` (cross-talk C, per-axis gain error G);
    first-order low-pass at ``bandwidth_hz``; + constant bias + thermal zero drift
    ``k·(T − T_ambient)`` + random-walk drift + white noise; saturation at ``±range``;
    quantization to ``resolution``. The temperature is
    ``T(t) = T_ambient + ΔT·(1 − exp(−t/τ))`` (the wrist warming up from t = 0). Noise is a
    pure function of (seed, sample index), so a run is reproducible from its seed and
    contexts can be cloned freely.
    """

    _BLOCK = 4096  # samples of noise drawn at once

    def __init__(self, config: SensorConfig):
        super().__init__()
        config.validate()
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
        # Three state groups so the outputs are plain state ports (no Python call per read).
        self._internal = self.DeclareDiscreteState(13)  # filter (6), drift (6), sample count
        self._reading = self.DeclareDiscreteState(6)
        self._saturated = self.DeclareDiscreteState(1)
        self._temperature_state = self.DeclareDiscreteState([self._temperature[0]])
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

    # -- what the sensor does to a wrench without randomness ---------------------------------
    def get_input_port_wrench_ideal(self):
        return self.GetInputPort("wrench_ideal")

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
        temperature[0] = _temperature_at(internal[12], self._constants[13])
        if not self._on:
            _ideal_sample(internal, w, reading, saturated)
            return
        block, noise = self._noise
        if not _imperfect_sample(internal, w, self._constants, block, noise, reading, saturated):
            # This sample's draws are in another block (every 4096 samples, or a new run).
            block = int(internal[12]) // self._BLOCK
            self._noise = (block, _noise_block(self.config.seed, block, self._BLOCK))
            _imperfect_sample(internal, w, self._constants, *self._noise, reading, saturated)


@numba.njit(cache=True)
def _imperfect_sample(internal, w, constants, block, noise_block, reading, saturated):
    """One sample of the imperfect sensor, written in place; False (nothing written) if this
    sample's draws are not in `noise_block`.

    `internal` is [filter (6), drift (6), sample count]; `constants` as built in
    NoisyForceTorqueSensor.__init__; `noise_block` is block number `block` of the draws
    (12 per sample: white noise then drift increments).
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
def _noise_block(seed: int, block: int, size: int) -> np.ndarray:
    """Standard normal draws (size × 12) for samples [block·size, (block+1)·size)."""
    return np.random.default_rng([seed, block]).standard_normal((size, 12))


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
