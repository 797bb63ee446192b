"""The compiled path's chain update: what :meth:`ftdrake.runtime.step.ChainStep.update` does
for one F/T sample, on the ChainStep's own arrays, from compiled code.

Supported (:func:`chain_problem` says why not otherwise): a compensator with a fused loop
update (the forest, the physics payload model, the hybrid; :data:`KINDS`), neither
temperature nor IMU; the bias tracker off, or on without payload tracking (no joint-state
gravity) and without the payload-change monitor; no wrench delay line. The default chain
is one. The order is ChainStep's: the detector on the tracker's contact wrench from before
the update (without a tracker, on the compensated wrench), the tracker on the compensated
wrench from before it, then the compensator
(tests/hardware/test_fast_chain.py checks the outputs equal ChainStep's, bit for bit).

Which fused update runs is chosen at compile time by the type of a marker array
(:func:`marker`), so that the loop calling it is one cacheable function per model kind (a
compiled function taking another as an argument is not cacheable).
"""

from __future__ import annotations

import numba
import numpy as np
from numba.extending import overload

from ...compensation.compiled.loop import (
    FAULT,
    FAULT_CHANGED,
    OOD,
    OOD_CHANGED,
    compensate_with_forest,
    compensate_with_hybrid,
    compensate_with_payload,
)
from ...runtime.bias_estimator import track_sample
from ...runtime.detector import _detect, _in_quadrature, detect_chi2

#: The fused updates the compiled path runs, and the dtype of their marker.
KINDS = {compensate_with_forest: np.int8, compensate_with_payload: np.int16,
         compensate_with_hybrid: np.int32}


def marker(update) -> np.ndarray:
    """The empty array whose dtype selects `update` in :func:`compensate`."""
    return np.zeros(0, dtype=KINDS[update])


def compensate(kind, wrench, x, no_accel, estimator, lo, hi, constants, to_S, arrays,
               internal, external, std):
    """The fused update `kind` (a :func:`marker`) selects; compiled code only."""
    raise NotImplementedError("compensate runs in compiled code only")


def _calling(update):
    def impl(kind, wrench, x, no_accel, estimator, lo, hi,  # noqa: ARG001 (the stub's)
             constants, to_S, arrays, internal, external, std):
        return update(wrench, x, no_accel, False, estimator, lo, hi, constants, to_S, *arrays,
                      internal, external, std)
    return impl


@overload(compensate)
def _compensate(kind, wrench, x, no_accel, estimator, lo, hi,  # noqa: ARG001 (the stub's)
                constants, to_S, arrays, internal, external, std):  # noqa: ARG001
    for update, dtype in KINDS.items():
        if kind.dtype == numba.from_dtype(np.dtype(dtype)):
            return _calling(update)
    return None


@numba.njit(cache=True)
def _judge(w, std, chi2, constants, flag, counter, force) -> None:
    if chi2:
        detect_chi2(w, std, constants, flag, counter, force)
    else:
        _detect(w, std, constants, flag, counter, force)


@numba.njit(cache=True)
def chain_update(t, wrench, x, kind, comp, arrays, detector, tracker) -> None:
    """One update at chain time `t` (s) with the inputs `wrench` (6) and `x` (2n) (already
    in the step's input arrays); `comp`, `detector`, `tracker`: :func:`step_arguments`."""
    no_accel, estimator, lo, hi, constants, to_S, internal, external, std, ood, fault = comp
    (arm_after, uses_std, chi2, det_constants, flag, counter, force, std_both,
     no_std) = detector
    (flags, g, motion, n, payload_map, x_tracker, tracker_constants, steps, noise_std,
     prior_std, corrected, bias, payload, inertia, tracking, tracker_std) = tracker
    if n == 0:  # no tracker: the detector on the compensated wrench (ChainStep's)
        if t >= arm_after:
            _judge(external, std if uses_std else no_std, chi2, det_constants, flag, counter,
                   force)
    else:
        flags[0] = flag[0]  # the detector's flag before it updates
        if t >= arm_after:
            judged = _in_quadrature(std, tracker_std, std_both) if uses_std else no_std
            _judge(corrected, judged, chi2, det_constants, flag, counter, force)
        flags[1], flags[2], flags[3], flags[4] = ood[0], max(fault[0], 0.0), 0.0, 0.0
        track_sample(external, g, motion, flags, n, payload_map, x_tracker,
                     tracker_constants, steps, noise_std, prior_std, corrected, bias, payload,
                     inertia, tracking, tracker_std)
    status = compensate(kind, wrench, x, no_accel, estimator, lo, hi, constants, to_S, arrays,
                        internal, external, std)
    if status & FAULT_CHANGED:
        fault[0] = 1.0 if status & FAULT else 0.0
    if status & OOD_CHANGED:
        ood[0] = 1.0 if status & OOD else 0.0


def chain_problem(step) -> str | None:
    """Why :func:`chain_update` cannot update `step`'s chain (None: it can)."""
    chain, comp = step.chain, step._comp
    if comp._fused is None or comp._fused[0] not in KINDS:
        return f"the model ({type(comp.model).__name__}) has no compiled loop update it runs"
    if step.needs_temperature or step.needs_imu:
        return "the model takes the sensor temperature or an IMU"
    tracks_payload = step._tracker is not None and step._tracker.track_payload
    if tracks_payload or step._gravity is not None or step._monitor is not None:
        return "the bias tracker tracks the payload (chain.bias_tracker.track_payload)"
    if step._line is not None:
        return "the wrench is delayed against the joint state (chain.sensor.wrench_delay_s)"
    if chain.detector is None:
        return "the chain has no contact detector"
    return None


def step_arguments(step) -> tuple:
    """(kind, comp, arrays, detector, tracker): the arguments of :func:`chain_update` on the
    ChainStep `step`'s own arrays (the compiled update changes its state in place)."""
    comp, detector, tracker = step._comp, step._detector, step._tracker
    update, arrays = comp._fused
    estimator, internal, external, std, ood, fault = step._comp_state
    comp_args = (step._no_acceleration, estimator, comp._lo, comp._hi, comp._constants,
                 comp._to_S, internal, external, std, ood, fault)
    detector_args = (float(detector.arm_after_s), bool(detector.uses_std), bool(detector._chi2),
                     detector._constants, step._flag, step._counter, step._force,
                     detector._std, detector._no_std)
    if tracker is None:  # the types of a tracker's arguments, n = 0 saying there is none
        none = np.zeros(6)
        tracker_args = (np.zeros(5), np.zeros(3), none, 0, np.zeros((6, 0)), none, none, none,
                        none, none, none, none, none, none, none, none)
    else:
        x_tracker, corrected, bias = step._tracker_state
        motion = step._motion if step._motion_used else step._no_motion
        tracker_args = (step._flags, step._g, motion, int(tracker.n), tracker.payload_map,
                        x_tracker, tracker._constants, tracker._steps, tracker.noise_std,
                        tracker.prior_std, corrected, bias, step._payload, step._inertia,
                        step._tracking, step._tracker_std)
    return marker(update), comp_args, tuple(arrays), detector_args, tracker_args
