"""serve's per-message path compiled, as a prototype: what a compiled loop doing ftdrake's
chain work costs per message on ROS 2 (`live_rate.py --echo chain`, which starts
``transport_echo.py ros2 DOMAIN chain MODEL`` in serve's place).

The node, readers, writers and wait set are made in Python as serve makes them; the chain
(:class:`~ftdrake.runtime.step.ChainStep` of the default ``ChainConfig``: the model's
compensator, the bias tracker, the detector) is built and initialised in Python, and its
state arrays are handed to one numba function run without the GIL. Per wake-up it waits on
the wait set, takes both readers' samples as serialised data (``compiled_echo.py``'s
declarations of Cyclone DDS's C functions), reads the JointState's q and q̇ and the
WrenchStamped's wrench from their CDR bytes, updates the chain with the compiled kernels
the ChainStep calls (the detector on the tracker's contact wrench, the tracker, the fused
compensator update: ``ChainStep.update`` without its Python), and writes serve's five
default outputs: ``wrench_compensated``, ``wrench_contact`` and ``bias`` (WrenchStamped,
the input's header), ``contact`` (Bool) and ``contact_force`` (Float64).

Left out, so what it measures is a lower bound of such a loop: the stream checks (stamps,
rates, timeouts, the joint names: the driver's order must be the model's), the pairing by
stamps (the newest joint state is used), the bridging of gaps, the overload accounting,
the latencies, the status and diagnostics, faults (a fault's output is still written). A
measurement, not part of ftdrake. ``python benchmarks/compiled_serve.py`` checks its chain
update against ``ChainStep.update`` on the same messages (:func:`check`).
"""

from __future__ import annotations

import numba
import numpy as np
from compiled_echo import (
    INFO_BYTES,
    MAX_SAMPLES,
    VALID_DATA,
    serdata_unref,
    serialized,
    sertype_of,
    take,
    waitset_wait,
    write_bytes,
)

from ftdrake.compensation.compiled.loop import FAULT, FAULT_CHANGED, OOD, OOD_CHANGED
from ftdrake.runtime.bias_estimator import track_sample
from ftdrake.runtime.detector import _detect, _in_quadrature, detect_chi2


@numba.njit(cache=True)
def _u32(buf, at) -> int:
    return (buf[at] | (buf[at + 1] << 8) | (buf[at + 2] << 16)
            | (numba.uint32(buf[at + 3]) << 24))


@numba.njit(cache=True)
def _align(at, size) -> int:
    """The CDR body starts at byte 4 (after the encapsulation header)."""
    return 4 + ((at - 4 + size - 1) // size) * size


@numba.njit(cache=True)
def _doubles(buf, at, out, scratch) -> None:
    for i in range(len(out)):
        scratch[:] = buf[at + 8 * i:at + 8 * i + 8]
        out[i] = scratch.view(np.float64)[0]


@numba.njit(cache=True)
def _after_header(buf) -> int:
    """The offset after a std_msgs/Header (stamp, frame_id)."""
    return 16 + _u32(buf, 12)


@numba.njit(cache=True)
def read_joint_state(buf, n, x, scratch) -> bool:
    """q, q̇ of a JointState's CDR into x (2n); False unless it holds n of each."""
    at = _after_header(buf)
    at = _align(at, 4)
    names = _u32(buf, at)
    at += 4
    for _ in range(names):
        at = _align(at, 4)
        at += 4 + _u32(buf, at)
    for part in range(2):  # position, velocity
        at = _align(at, 4)
        if _u32(buf, at) != n:
            return False
        at = _align(at + 4, 8)
        _doubles(buf, at, x[part * n:(part + 1) * n], scratch)
        at += 8 * n
    return True


@numba.njit(cache=False)  # it calls Cyclone's C functions (their addresses)
def write_wrench(writer, sertype, head, head_size, out, values, iov, scratch) -> int:
    """A WrenchStamped with the input's header bytes (`head`) and `values` (6)."""
    out[:head_size] = head[:head_size]
    for i in range(6):
        scratch.view(np.float64)[0] = values[i]
        out[head_size + 8 * i:head_size + 8 * i + 8] = scratch
    return write_bytes(writer, sertype, out.ctypes.data, head_size + 48, iov)


@numba.njit(cache=False)  # it calls Cyclone's C functions (their addresses)
def write_value(writer, sertype, out, value, is_bool, iov, scratch) -> int:
    """A std_msgs Bool (padded to 8 bytes, as ftdrake's writer sends) or Float64."""
    out[0], out[1], out[2], out[3] = 0, 1, 0, 0  # CDR, little-endian
    if is_bool:
        out[4:8] = 0
        out[4] = 1 if value > 0.5 else 0
    else:
        scratch.view(np.float64)[0] = value
        out[4:12] = scratch
    return write_bytes(writer, sertype, out.ctypes.data, 8 if is_bool else 12, iov)


@numba.njit(cache=True)
def _detect_and_track(t, detector, tracker, comp) -> None:
    """ChainStep.update's tracker side on the default chain: the detector on the tracker's
    contact wrench (state before this update), then the tracker."""
    (arm_after, uses_std, chi2, det_constants, flag, counter, force, std_both) = detector
    (flags, g, motion, n, payload_map, x_tracker, constants, steps, noise_std, prior_std,
     corrected, bias, payload, inertia, tracking, tracker_std) = tracker
    external, std, ood, fault = comp[7], comp[8], comp[9], comp[10]
    flags[0] = flag[0]
    if t >= arm_after:
        if uses_std:
            _in_quadrature(std, tracker_std, std_both)
        if chi2:
            detect_chi2(corrected, std_both, det_constants, flag, counter, force)
        else:
            _detect(corrected, std_both, det_constants, flag, counter, force)
    flags[1], flags[2], flags[3], flags[4] = ood[0], fault[0], 0.0, 0.0
    track_sample(external, g, motion, flags, n, payload_map, x_tracker, constants, steps,
                 noise_std, prior_std, corrected, bias, payload, inertia, tracking, tracker_std)


@numba.njit(cache=False)  # it writes through Cyclone (write_value, write_wrench)
def _write_outputs(entities, sertypes, data, head, out, iov, scratch, detector, tracker,
                   comp) -> int:
    """serve's five outputs; the number of writes that failed."""
    flag, force = detector[4], detector[6]
    errors = 0
    for k, values in ((3, comp[7]), (4, tracker[10]), (5, tracker[11])):
        errors += write_wrench(entities[k], sertypes[k - 3], data, head, out, values, iov,
                               scratch) != 0
    errors += write_value(entities[6], sertypes[3], out, flag[0], True, iov, scratch) != 0
    errors += write_value(entities[7], sertypes[4], out, force[0], False, iov, scratch) != 0
    return errors


@numba.njit(cache=True)
def _status_flags(status, ood, fault) -> None:
    if status & FAULT_CHANGED:
        fault[0] = 1.0 if status & FAULT else 0.0
    if status & OOD_CHANGED:
        ood[0] = 1.0 if status & OOD else 0.0


def make_loop(update):
    """The compiled loop around the compensator's fused update `update`
    (``model.fused_loop_update()[0]``), and its chain update of one sample (for
    :func:`check`); compiled at their first call."""

    @numba.njit(nogil=True)
    def chain_sample(data, x, wrench, scratch, t, detector, tracker, comp,
                     comp_arrays) -> int:
        """The wrench of the WrenchStamped's CDR `data` and the chain's update at `t` with
        the joint state `x`; returns the offset of the wrench in `data` (after the header)."""
        head = _align(_after_header(data), 8)
        _doubles(data, head, wrench, scratch)
        _detect_and_track(t, detector, tracker, comp)
        (no_accel, estimator, lo, hi, constants, to_S, internal, external, std, ood,
         fault) = comp
        status = update(wrench, x, no_accel, False, estimator, lo, hi, constants, to_S,
                        *comp_arrays, internal, external, std)
        _status_flags(status, ood, fault)
        return head

    @numba.njit(nogil=True)
    def on_wrench(data, out, iov, scratch, x, wrench, entities, sertypes, period, detector,
                  tracker, comp, comp_arrays, counts) -> None:
        head = chain_sample(data, x, wrench, scratch, counts[0] * period, detector, tracker,
                            comp, comp_arrays)
        counts[2] += _write_outputs(entities, sertypes, data, head, out, iov, scratch,
                                    detector, tracker, comp)
        counts[0] += 1

    @numba.njit(nogil=True)
    def loop(entities, sertypes, mask, samples, infos, data, out, iov, scratch, x, wrench,
             period, detector, tracker, comp, comp_arrays, counts, rounds, timeout_ns):
        n = len(x) // 2  # joints
        for _ in range(rounds):
            waitset_wait(entities[0], 0, 0, timeout_ns)
            for slot in (2, 1):  # the joint states first
                for i in range(take(entities[slot], mask, samples, infos)):
                    if infos[i * INFO_BYTES + VALID_DATA]:
                        if serialized(samples[i], data) < 0:
                            counts[2] += 1
                        elif slot == 2:
                            counts[1] += read_joint_state(data, n, x, scratch)
                        else:
                            on_wrench(data, out, iov, scratch, x, wrench, entities, sertypes,
                                      period, detector, tracker, comp, comp_arrays, counts)
                    serdata_unref(samples[i])

    return loop, chain_sample


def chain_arguments(model) -> tuple:
    """A default chain's ChainStep on `model` and the compiled loop's views of its state:
    (step, update, arrays, detector, tracker, compensator)."""
    from ftdrake import ChainConfig, CompensationChain
    from ftdrake.runtime.step import ChainStep

    step = ChainStep(CompensationChain(model, ChainConfig(), n_joints=model.n_joints_))
    comp, detector, tracker = step._comp, step._detector, step._tracker
    if comp._fused is None:
        raise RuntimeError(f"{type(model).__name__} has no fused loop update")
    update, arrays = comp._fused
    detector_args = (detector.arm_after_s, detector.uses_std, detector._chi2,
                     detector._constants, step._flag, step._counter, step._force, np.zeros(6))
    x_tracker, corrected, bias = step._tracker_state
    tracker_args = (step._flags, step._g, step._no_motion, tracker.n, tracker.payload_map,
                    x_tracker, tracker._constants, tracker._steps, tracker.noise_std,
                    tracker.prior_std, corrected, bias, step._payload, step._inertia,
                    step._tracking, step._tracker_std)
    comp_args = (step._no_acceleration, *step._comp_state[:1], comp._lo, comp._hi,
                 comp._constants, comp._to_S, *step._comp_state[1:])
    return step, update, tuple(arrays), detector_args, tracker_args, comp_args


def chain_spin(node, model_path, wrench_reader, joint_reader, writers, counts):
    """The function the echo's loop calls: 20 compiled wake-ups of up to 2 ms, then back to
    Python. `writers`: wrench_compensated, wrench_contact, bias, contact, contact_force."""
    from cyclonedds.core import InstanceState, SampleState, ViewState

    from ftdrake import load_model

    step, update, arrays, *state = chain_arguments(load_model(model_path))
    entities = np.array([node._waitset._ref, wrench_reader._ref, joint_reader._ref,
                         *(w._ref for w in writers)], dtype=np.int32)
    sertypes = np.array([sertype_of(w._ref) for w in writers], dtype=np.uint64)
    mask = int(SampleState.Any | ViewState.Any | InstanceState.Any)
    buffers = (np.zeros(MAX_SAMPLES, dtype=np.uint64),
               np.zeros(MAX_SAMPLES * INFO_BYTES, dtype=np.uint8),
               np.zeros(4096, dtype=np.uint8), np.zeros(4096, dtype=np.uint8),
               np.zeros(2, dtype=np.uint64), np.zeros(8, dtype=np.uint8))
    x, wrench = np.zeros(2 * step.n_joints), np.zeros(6)
    compiled = np.zeros(3, dtype=np.int64)
    loop, _ = make_loop(update)

    def spin(rounds: int = 20) -> None:
        loop(entities, sertypes, mask, *buffers, x, wrench, step.period, *state, arrays,
             compiled, rounds, 2_000_000)
        counts["ft"], counts["joint"] = int(compiled[0]), int(compiled[1])
        if compiled[2]:
            raise RuntimeError(f"{compiled[2]} writes failed or samples did not fit")

    spin(0)  # compiles
    return spin


def check(samples: int = 3000) -> dict:
    """The compiled chain update against ChainStep.update on the same messages (CDR bytes
    as a driver writes them): free motion of ftdrake's arm at 1 kHz with a 20 N push along
    z for 0.2 s, both models of ``live_step.py``; {model: (max |difference| over the five
    outputs, samples in contact)}."""
    from live_step import N, models_and_stream

    from ftdrake.hardware.ros2.messages import header, ros2_type, wrench_stamped

    models, rows, Y = models_and_stream(samples)
    states, Y = rows[:, :2 * N], Y.copy()
    Y[samples // 2:samples // 2 + 200, 2] += 20.0  # N: a push
    joint_state = ros2_type("sensor_msgs/msg/JointState")
    names = [f"joint_{k}" for k in range(N)]
    result = {}
    for name, model in models.items():
        reference = chain_arguments(model)[0]
        step, update, arrays, detector, tracker, comp = chain_arguments(model)
        _, chain_sample = make_loop(update)
        x, wrench, scratch = np.zeros(2 * N), np.zeros(6), np.zeros(8, dtype=np.uint8)
        worst, contacts = 0.0, 0
        for k in range(samples):
            t = (k + 1) * 1e-3
            data = [np.frombuffer(message.serialize(), dtype=np.uint8).copy() for message in (
                joint_state(header=header(t), name=names, position=states[k, :N].tolist(),
                            velocity=states[k, N:].tolist(), effort=[]),
                wrench_stamped(header(t, "ft_sensor"), Y[k].tolist()))]
            if not read_joint_state(data[0], N, x, scratch):
                raise RuntimeError("a JointState did not read")
            chain_sample(data[1], x, wrench, scratch, k * step.period, detector, tracker,
                         comp, arrays)
            expected = reference.update(k * reference.period, Y[k], states[k])
            for key, got in (("wrench_compensated", comp[7]), ("wrench_contact", tracker[10]),
                             ("bias", tracker[11]), ("contact", detector[4]),
                             ("contact_force", detector[6])):
                worst = max(worst, float(np.abs(expected[key] - got).max()))
            contacts += int(expected["contact"][0] > 0.5)
        result[name] = (worst, contacts)
        print(f"{name}: max |compiled − ChainStep| over {samples} samples {worst:.3g}; "
              f"{contacts} samples in contact", flush=True)
    return result


if __name__ == "__main__":
    check()
