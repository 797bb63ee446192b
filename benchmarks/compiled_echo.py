"""The ROS 2 echo of ``transport_echo.py`` with its per-message loop compiled: how far below
Python's floor a compiled per-message path could go on Cyclone DDS (`live_rate.py --echo
compiled`).

The node, its readers, writers and wait set are made in Python as for the other deliveries
(``Ros2Node``); then one numba function, run without the GIL, does the loop: wait on the
wait set, take each reader's samples as serialized data (``dds_takecdr``), and for each
wrench write its bytes back on ``wrench_contact`` and a ``Bool`` false on ``contact``
(``ddsi_serdata_from_ser_iov`` on the writer's type, ``dds_writecdr``). It calls Cyclone's
C functions through ctypes declarations written here: the cyclonedds wheel ships no
headers, so these follow Cyclone DDS 11.0's signatures and its ``dds_sample_info_t`` (64
bytes on x86-64, ``valid_data`` at byte 12), which this prototype assumes and checks only
by every echo arriving (the driver counts what comes back: a wrong stride, tried first,
lost 2–3 of 11 000). A measurement, not part of ftdrake.
"""

from __future__ import annotations

import ctypes
import glob
import os
from ctypes import c_int32, c_int64, c_uint32, c_uint64

import numba
import numpy as np

INFO_BYTES = 64  # sizeof(dds_sample_info_t), Cyclone DDS 11 on x86-64: the infos' stride
VALID_DATA = 12  # its valid_data byte
SDK_DATA = 2  # enum ddsi_serdata_kind
MAX_SAMPLES = 64


def _libddsc():
    import cyclonedds

    base = os.path.dirname(cyclonedds.__file__)
    found = glob.glob(os.path.join(base, os.pardir, "cyclonedds.libs", "libddsc*.so*"))
    if not found:
        raise RuntimeError(f"no libddsc in {base}/../cyclonedds.libs")
    return ctypes.CDLL(found[0])


_lib = _libddsc()


def _function(name, result, *arguments):
    function = getattr(_lib, name)
    function.restype, function.argtypes = result, list(arguments)
    return function


# Pointers as 64-bit integers (x86-64): numba passes them as they are.
waitset_wait = _function("dds_waitset_wait", c_int32, c_int32, c_uint64, c_uint64, c_int64)
takecdr = _function("dds_takecdr", c_int32, c_int32, c_uint64, c_uint32, c_uint64, c_uint32)
writecdr = _function("dds_writecdr", c_int32, c_int32, c_uint64)
serdata_size = _function("ddsi_serdata_size", c_uint32, c_uint64)
serdata_to_ser = _function("ddsi_serdata_to_ser", None, c_uint64, c_uint64, c_uint64,
                           c_uint64)
serdata_from_ser_iov = _function("ddsi_serdata_from_ser_iov", c_uint64, c_uint64, c_uint32,
                                 c_uint64, c_uint64, c_uint64)
serdata_unref = _function("ddsi_serdata_unref", None, c_uint64)
get_entity_sertype = _function("dds_get_entity_sertype", c_int32, c_int32, c_uint64)


@numba.njit(nogil=True, cache=False)
def write_bytes(writer, sertype, data, size, iov) -> int:
    """Writes the `size` CDR bytes at address `data` on `writer` (its type `sertype`);
    Cyclone's return code (0: written)."""
    iov[0], iov[1] = data, size
    return writecdr(writer, serdata_from_ser_iov(sertype, SDK_DATA, 1, iov.ctypes.data, size))


@numba.njit(nogil=True, cache=False)
def take(reader, mask, samples, infos) -> int:
    """Takes the reader's samples as serialised data into `samples` (their infos into
    `infos`); how many (0 on an error)."""
    return max(takecdr(reader, samples.ctypes.data, samples.shape[0], infos.ctypes.data,
                       mask), 0)


@numba.njit(nogil=True, cache=False)
def serialized(sample, data) -> int:
    """A taken sample's CDR bytes into `data`; their size, or -1 when they do not fit (then
    nothing is read: the caller counts it as an error)."""
    size = serdata_size(sample)
    if size > data.shape[0]:
        return -1
    serdata_to_ser(sample, 0, size, data.ctypes.data)
    return size


@numba.njit(nogil=True, cache=False)
def echo_rounds(entities, sertypes, mask, samples, infos, data, iov, contact, counts,
                rounds, timeout_ns) -> None:
    """`rounds` wake-ups: entities = [wait set, wrench reader, joint reader, wrench writer,
    contact writer], sertypes = [wrench writer's, contact writer's]; counts [wrenches,
    joint states, errors (a write that failed, a sample too large to read)] += what was
    handled."""
    for _ in range(rounds):
        waitset_wait(entities[0], 0, 0, timeout_ns)
        for slot in (2, 1):  # the joint states first, as the station's spin
            for i in range(take(entities[slot], mask, samples, infos)):
                if infos[i * INFO_BYTES + VALID_DATA]:
                    if slot == 2:
                        counts[1] += 1
                    elif (size := serialized(samples[i], data)) < 0:
                        counts[2] += 1
                    else:
                        counts[2] += write_bytes(entities[3], sertypes[0], data.ctypes.data,
                                                 size, iov) != 0
                        counts[2] += write_bytes(entities[4], sertypes[1],
                                                 contact.ctypes.data, contact.shape[0],
                                                 iov) != 0
                        counts[0] += 1
                serdata_unref(samples[i])


def sertype_of(entity: int) -> int:
    found = np.zeros(1, dtype=np.uint64)
    status = get_entity_sertype(entity, found.ctypes.data)
    if status != 0:
        raise RuntimeError(f"dds_get_entity_sertype({entity}) returned {status}")
    return int(found[0])


def compiled_spin(node, wrench_reader, joint_reader, wrench_writer, contact_writer, counts):
    """The function serve's loop calls: 20 compiled wake-ups of up to 2 ms each, then back
    to Python (for SIGINT). `counts` (serve's dict) follows the compiled counts."""
    from cyclonedds.core import InstanceState, SampleState, ViewState

    entities = np.array([node._waitset._ref, wrench_reader._ref, joint_reader._ref,
                         wrench_writer._ref, contact_writer._ref], dtype=np.int32)
    sertypes = np.array([sertype_of(wrench_writer._ref), sertype_of(contact_writer._ref)],
                        dtype=np.uint64)
    mask = int(SampleState.Any | ViewState.Any | InstanceState.Any)
    samples = np.zeros(MAX_SAMPLES, dtype=np.uint64)
    infos = np.zeros(MAX_SAMPLES * INFO_BYTES, dtype=np.uint8)
    data = np.zeros(4096, dtype=np.uint8)
    iov = np.zeros(2, dtype=np.uint64)
    # std_msgs/Bool false: CDR little-endian header, then the byte padded to 4, as
    # ftdrake's ValueWriter sends it.
    contact = np.array([0, 1, 0, 0, 0, 0, 0, 0], dtype=np.uint8)
    compiled = np.zeros(3, dtype=np.int64)

    def spin() -> None:
        echo_rounds(entities, sertypes, mask, samples, infos, data, iov, contact, compiled,
                    20, 2_000_000)
        counts["ft"], counts["joint"] = int(compiled[0]), int(compiled[1])
        if compiled[2]:
            raise RuntimeError(f"{compiled[2]} writes failed or samples did not fit")

    spin()  # compiles
    return spin
