"""One control-loop sample in compiled code: input checks, the q̈ estimate, the prediction and
the compensated wrench.

``CompensatorSystem`` runs every sample through a *fused update*, a numba function with the
signature::

    update(wrench (6), x (2n) [q; v], accel (n), measured (bool), estimator (3n + 3),
           lo, hi (used inputs' training range), constants [g, h, period], to_S (6 × 6 or 0 × 6),
           *arrays, internal (6), external (6), std (6)) -> status bits

that checks the inputs (:func:`prepare_row`), predicts the internal wrench and its std into
`internal` and `std`, and writes ``external = to_S · (wrench − internal)``
(:func:`external_wrench`). A compensator offers one through its ``fused_loop_update()``
(the compensator protocol, :mod:`ftdrake.compensation.estimators.base`), returning ``(update,
arrays)``: the forest's, the physics payload model's and the hybrid's are below;
:func:`fused_update` builds one from any compiled row kernel ``kernel(row (3n), *arrays,
mean (6), std (6))``.

Status bits: :data:`FAULT` (NaN/inf in the inputs: nothing written but the fault copy),
:data:`FAULT_CHANGED`, :data:`OOD` (a used input outside its training range),
:data:`OOD_CHANGED`.
"""

from __future__ import annotations

import numba
import numpy as np

from ...signals import causal_acceleration_step, hold_acceleration
from .forest import forest_accumulate_with_std
from .hybrid import hybrid_row
from .payload import payload_mean_std

# Bits of the status a fused update returns.
FAULT = 1
FAULT_CHANGED = 2
OOD = 4
OOD_CHANGED = 8


@numba.njit(cache=True)
def prepare_row(wrench, x, accel, measured, estimator, row, lo, hi, constants):
    """Checks the inputs and builds the feature row [q, v, v̇] in place.

    On NaN/inf in any input, writes nothing but the fault copy and returns FAULT. Otherwise
    updates the acceleration estimator (:func:`~ftdrake.signals.causal_acceleration_step`
    with ``constants = [g, h, period]``) unless `measured`, and checks the used inputs against
    [lo, hi]. Returns the status bits.
    """
    n = len(accel)
    fault_slot, ood_slot = len(estimator) - 2, len(estimator) - 1  # after the q̈ estimator's
    finite = True
    for value in wrench:
        finite = finite and np.isfinite(value)
    for value in x:
        finite = finite and np.isfinite(value)
    if measured:
        for value in accel:
            finite = finite and np.isfinite(value)
    status = 0
    if not finite:
        if estimator[fault_slot] == 0.0:
            estimator[fault_slot] = 1.0
            status |= FAULT_CHANGED
        return status | FAULT
    if estimator[fault_slot] != 0.0:
        estimator[fault_slot] = 0.0
        status |= FAULT_CHANGED
    if measured:
        hold_acceleration(x[n:2 * n], accel, estimator)
        for i in range(n):
            row[2 * n + i] = accel[i]
    else:
        causal_acceleration_step(x[n:2 * n], estimator, constants[0], constants[1],
                                 constants[2], row[2 * n:3 * n])
    for i in range(2 * n):
        row[i] = x[i]
    ood = False
    for i in range(len(lo)):
        ood = ood or row[i] < lo[i] or row[i] > hi[i]
    if ood != (estimator[ood_slot] != 0.0):
        estimator[ood_slot] = 1.0 if ood else 0.0
        status |= OOD_CHANGED
    return status | (OOD if ood else 0)


@numba.njit(cache=True)
def external_wrench(wrench, internal, to_S, external):
    """external = to_S · (wrench − internal), or wrench − internal when to_S is (0, 6)."""
    if to_S.shape[0] == 0:
        for j in range(6):
            external[j] = wrench[j] - internal[j]
        return
    for i in range(6):
        total = 0.0
        for j in range(6):
            total += to_S[i, j] * (wrench[j] - internal[j])
        external[i] = total


@numba.njit(cache=True)
def compensate_with_forest(wrench, x, accel, measured, estimator, lo, hi, constants, to_S,
                           nodes, leaf_values, trees, n_trees, internal, external, std):
    """prepare_row, then the compiled forest into `internal` (and its spread across trees
    into `std`) and the external wrench (:func:`external_wrench`)."""
    row = np.empty(3 * len(accel))
    status = prepare_row(wrench, x, accel, measured, estimator, row, lo, hi, constants)
    if not status & FAULT:
        forest_accumulate_with_std(row, nodes, leaf_values, trees, n_trees, internal, std)
        external_wrench(wrench, internal, to_S, external)
    return status


@numba.njit(cache=True)
def compensate_with_payload(wrench, x, accel, measured, estimator, lo, hi, constants, to_S,
                            reals, ints, internal, external, std):
    """prepare_row, then the physics payload model
    (:func:`~ftdrake.compensation.compiled.payload.payload_mean_std`) into `internal` and
    `std`, and the external wrench (:func:`external_wrench`)."""
    row = np.empty(3 * len(accel))
    status = prepare_row(wrench, x, accel, measured, estimator, row, lo, hi, constants)
    if not status & FAULT:
        payload_mean_std(row, reals, ints, internal, std)
        external_wrench(wrench, internal, to_S, external)
    return status


@numba.njit(cache=True)
def compensate_with_hybrid(wrench, x, accel, measured, estimator, lo, hi, constants, to_S,
                           reals, ints, nodes, leaf_values, trees, n_trees, points, kd_nodes,
                           splits, center, scale, var, length, internal, external, std):
    """prepare_row, then the hybrid's payload model and residual forest
    (:func:`~ftdrake.compensation.compiled.hybrid.hybrid_row`) into `internal` and `std`,
    and the external wrench (:func:`external_wrench`)."""
    row = np.empty(3 * len(accel))
    status = prepare_row(wrench, x, accel, measured, estimator, row, lo, hi, constants)
    if not status & FAULT:
        hybrid_row(row, reals, ints, nodes, leaf_values, trees, n_trees, points, kd_nodes,
                   splits, center, scale, var, length, internal, std)
        external_wrench(wrench, internal, to_S, external)
    return status


def fused_update(row_kernel):
    """A fused update (module docstring) around `row_kernel`, a numba function
    ``kernel(row (3n), *arrays, mean (6), std (6))`` that writes the prediction and its std
    for one full-layout row. Compiled at its first call (not cached on disk: it is built at
    run time)."""

    @numba.njit
    def update(wrench, x, accel, measured, estimator, lo, hi, constants, to_S, *rest):
        # rest = (*arrays, internal, external, std)
        internal, external, std = rest[-3], rest[-2], rest[-1]
        row = np.empty(3 * len(accel))
        status = prepare_row(wrench, x, accel, measured, estimator, row, lo, hi, constants)
        if not status & FAULT:
            row_kernel(row, *rest[:-3], internal, std)
            external_wrench(wrench, internal, to_S, external)
        return status

    return update
