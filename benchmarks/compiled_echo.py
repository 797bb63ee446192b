"""The ROS 2 echo of ``transport_echo.py`` with its per-message loop compiled: the least a
compiled per-message path costs on Cyclone DDS (`live_rate.py --echo compiled`), to set
against serve's compiled path (:mod:`ftdrake.hardware.ros2.fast`), which does the same
take and write plus ftdrake's work.

The node, its readers, writers and wait set are made in Python as for the other deliveries
(``Ros2Node``); then one numba function, run without the GIL, does the loop with the
compiled path's own pieces (Cyclone's C functions as :mod:`ftdrake.hardware.ros2.fast.cyclone`
declares and checks them, its take and its write): wait on the wait set, take each
reader's samples as serialized data, and for each wrench write its bytes back on
``wrench_contact`` and a ``Bool`` false on ``contact``. A measurement, not part of ftdrake.
"""

from __future__ import annotations

import numba
import numpy as np

from ftdrake.hardware.ros2.fast import cyclone
from ftdrake.hardware.ros2.fast.loop import ITEMS, TAKE, _take_both, _write


@numba.njit(cache=True, nogil=True)
def echo_rounds(c, waitset, readers, writers, sertypes, mask, items, take_buffers, iov,
                contact, counts, rounds, timeout_ns) -> None:
    """`rounds` wake-ups: readers = [joint, wrench], writers = [wrench_contact, contact];
    counts [wrenches, joint states, errors (a write that failed, a sample too large to
    read)] += what was handled."""
    ptrs, _, streams = items
    samples, infos, data = take_buffers
    for _ in range(rounds):
        c[0](waitset, 0, 0, timeout_ns)
        count = _take_both(c, readers, mask, samples, infos, ptrs, items[1], streams, 0)
        for i in range(count):
            size = c[3](ptrs[i])
            if streams[i] == 0:
                counts[1] += 1
            elif size > len(data):
                counts[2] += 1
            else:
                c[4](ptrs[i], 0, size, data.ctypes.data)
                counts[2] += _write(c, writers[0], sertypes[0], data, size, iov)
                counts[2] += _write(c, writers[1], sertypes[1], contact, len(contact), iov)
                counts[0] += 1
            c[6](ptrs[i])


def compiled_spin(node, wrench_reader, joint_reader, wrench_writer, contact_writer, counts):
    """The function serve's loop calls: 20 compiled wake-ups of up to 2 ms each, then back
    to Python (for SIGINT). `counts` (serve's dict) follows the compiled counts."""
    from cyclonedds.core import InstanceState, SampleState, ViewState

    c = cyclone.load()
    if isinstance(c, str):
        raise RuntimeError(c)  # noqa: TRY004 (why the declarations cannot be had)
    problem = cyclone.self_test(node.participant, c)
    if problem is not None:
        raise RuntimeError(problem)
    readers = np.array([joint_reader._ref, wrench_reader._ref], dtype=np.int32)
    writers = np.array([wrench_writer._ref, contact_writer._ref], dtype=np.int32)
    sertypes = np.array([cyclone.sertype_of(w) for w in writers], dtype=np.uint64)
    mask = int(SampleState.Any | ViewState.Any | InstanceState.Any)
    items = (np.zeros(ITEMS, dtype=np.uint64), np.zeros(ITEMS, dtype=np.int64),
             np.zeros(ITEMS, dtype=np.int8))
    take_buffers = (np.zeros(TAKE, dtype=np.uint64),
                    np.zeros(TAKE * cyclone.INFO_BYTES, dtype=np.uint8),
                    np.zeros(4096, dtype=np.uint8))
    iov = np.zeros(2, dtype=np.uint64)
    # std_msgs/Bool false: CDR little-endian header, then the byte padded to 4, as
    # ftdrake's ValueWriter sends it.
    contact = np.array([0, 1, 0, 0, 0, 0, 0, 0], dtype=np.uint8)
    compiled = np.zeros(3, dtype=np.int64)

    def spin(rounds: int = 20) -> None:
        echo_rounds(c, node._waitset._ref, readers, writers, sertypes, mask, items,
                    take_buffers, iov, contact, compiled, rounds, 2_000_000)
        counts["ft"], counts["joint"] = int(compiled[0]), int(compiled[1])
        if compiled[2]:
            raise RuntimeError(f"{compiled[2]} writes failed or samples did not fit")

    spin(0)  # compiles
    return spin
