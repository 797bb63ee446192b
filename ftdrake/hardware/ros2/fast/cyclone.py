"""Cyclone DDS's C functions, for the compiled per-message path (:mod:`.path`).

The cyclonedds wheel ships its C library (``libddsc``) but no headers, so the functions the
compiled loop calls are declared here by hand, after Cyclone DDS 11's signatures, with
pointers passed as 64-bit integers (x86-64 Linux), and handed to the numba functions as
first-class function arguments (so that those stay cacheable: no address is compiled in).

What the declarations assume, and :func:`self_test` checks on the running library before
the compiled path is used (else the station keeps its Python path and says why):

* ``dds_sample_info_t`` is :data:`INFO_BYTES` long, ``valid_data`` (a bool) at byte
  :data:`VALID_DATA` and ``source_timestamp`` (int64 ns, the writer's clock) at
  :data:`SOURCE_TIMESTAMP`;
* ``dds_takecdr`` takes a reader's samples as serialised data (``ddsi_serdata`` pointers),
  ``ddsi_serdata_size``/``ddsi_serdata_to_ser`` give their CDR bytes (the 4-byte
  encapsulation header first), ``ddsi_serdata_from_ser_iov`` (kind :data:`SDK_DATA`) and
  ``dds_writecdr`` write CDR bytes on a writer of the type ``dds_get_entity_sertype`` gives.
"""

from __future__ import annotations

import ctypes
import glob
import importlib.metadata
import os
import platform
import sys
import time
from ctypes import c_int32, c_int64, c_uint32, c_uint64
from typing import NamedTuple

import numpy as np

INFO_BYTES = 64  # sizeof(dds_sample_info_t), Cyclone DDS 11 on x86-64: the infos' stride
VALID_DATA = 12  # its valid_data byte
SOURCE_TIMESTAMP = 16  # its source_timestamp (int64, ns)
SDK_DATA = 2  # enum ddsi_serdata_kind: a sample's data (not only its key)
CLOCK_MONOTONIC = 1  # Linux: time.monotonic's clock
#: The Cyclone DDS major version the declarations follow.
MAJOR = 11


class CycloneC(NamedTuple):
    """The C functions the compiled loop calls (ctypes function objects)."""

    waitset_wait: object
    takecdr: object
    writecdr: object
    serdata_size: object
    serdata_to_ser: object
    serdata_from_ser_iov: object
    serdata_unref: object
    clock_gettime: object


_loaded: CycloneC | str | None = None
_get_sertype = None  # dds_get_entity_sertype, once loaded


def _libddsc_path() -> str:
    import cyclonedds  # noqa: PLC0415 (cyclonedds only for ROS 2)

    base = os.path.dirname(cyclonedds.__file__)
    found = sorted(glob.glob(os.path.join(base, os.pardir, "cyclonedds.libs", "libddsc*.so*")))
    if not found:
        raise OSError(f"no libddsc in {os.path.normpath(base + '/../cyclonedds.libs')}")
    return found[0]


def _function(lib, name, result, *arguments):
    function = getattr(lib, name)
    function.restype, function.argtypes = result, list(arguments)
    return function


def platform_problem() -> str | None:
    """Why the declarations cannot hold here (None: they may: see :func:`self_test`)."""
    if sys.platform != "linux" or platform.machine() != "x86_64":
        return f"declared for x86-64 Linux, this is {sys.platform} {platform.machine()}"
    try:
        version = importlib.metadata.version("cyclonedds")
    except importlib.metadata.PackageNotFoundError:
        return "cyclonedds is not installed"
    if version.split(".")[0] != str(MAJOR):
        return f"declared for Cyclone DDS {MAJOR}.x, cyclonedds is {version}"
    return None


def load() -> CycloneC | str:
    """The declared functions, or why they cannot be had (a sentence); loaded once."""
    global _loaded, _get_sertype
    if _loaded is None:
        problem = platform_problem()
        if problem is not None:
            _loaded = problem
            return _loaded
        try:
            lib, libc = ctypes.CDLL(_libddsc_path()), ctypes.CDLL(None)
            _loaded = CycloneC(
                _function(lib, "dds_waitset_wait", c_int32, c_int32, c_uint64, c_uint64,
                          c_int64),
                _function(lib, "dds_takecdr", c_int32, c_int32, c_uint64, c_uint32, c_uint64,
                          c_uint32),
                _function(lib, "dds_writecdr", c_int32, c_int32, c_uint64),
                _function(lib, "ddsi_serdata_size", c_uint32, c_uint64),
                _function(lib, "ddsi_serdata_to_ser", None, c_uint64, c_uint64, c_uint64,
                          c_uint64),
                _function(lib, "ddsi_serdata_from_ser_iov", c_uint64, c_uint64, c_uint32,
                          c_uint64, c_uint64, c_uint64),
                _function(lib, "ddsi_serdata_unref", None, c_uint64),
                _function(libc, "clock_gettime", c_int32, c_int32, c_uint64))
            _get_sertype = _function(lib, "dds_get_entity_sertype", c_int32, c_int32,
                                     c_uint64)
        except (OSError, AttributeError) as e:
            _loaded = f"Cyclone DDS's C library could not be loaded ({e})"
    return _loaded


def sertype_of(entity: int) -> int:
    """The ``ddsi_sertype`` pointer of a writer (`entity`: its handle), after load()."""
    found = np.zeros(1, dtype=np.uint64)
    status = _get_sertype(entity, found.ctypes.data)
    if status != 0:
        raise RuntimeError(f"dds_get_entity_sertype({entity}) returned {status}")
    return int(found[0])


def monotonic(c: CycloneC) -> float:
    """time.monotonic through the declared clock_gettime (the compiled loop's clock)."""
    spec = np.zeros(2, dtype=np.int64)
    c.clock_gettime(CLOCK_MONOTONIC, spec.ctypes.data)
    return float(spec[0]) + float(spec[1]) * 1e-9


def self_test(participant, c: CycloneC, samples: int = 3, timeout_s: float = 1.0) -> str | None:
    """Checks the declarations on the running library (None: they hold; else what failed):
    `samples` std_msgs/Float64 written on a private topic of `participant` are taken back
    with ``dds_takecdr``; each must be valid data with the value written and a source
    timestamp within a minute of now, in the order written; and the declared clock must be
    time.monotonic's."""
    from cyclonedds.core import InstanceState, SampleState, ViewState  # noqa: PLC0415
    from cyclonedds.pub import DataWriter  # noqa: PLC0415 (cyclonedds only for ROS 2)
    from cyclonedds.sub import DataReader  # noqa: PLC0415 (as above)
    from cyclonedds.topic import Topic  # noqa: PLC0415 (as above)

    from ..dds import qos  # noqa: PLC0415 (cyclonedds only for ROS 2)
    from ..messages import ros2_type  # noqa: PLC0415 (as above)

    before, now, after = time.monotonic(), monotonic(c), time.monotonic()
    if not before - 1e-3 <= now <= after + 1e-3:
        return f"clock_gettime gave {now:.6f} s, time.monotonic {before:.6f}–{after:.6f} s"
    kind = ros2_type("std_msgs/msg/Float64")
    topic = Topic(participant, f"ftdrake_abi_check_{os.getpid()}_{id(participant)}", kind)
    reader = DataReader(participant, topic, qos("reliable", 16))
    writer = DataWriter(participant, topic, qos("reliable", 16, writer=True))
    try:
        for k in range(samples):
            writer.write(kind(data=float(k) + 0.5))
        pointers = np.zeros(16, dtype=np.uint64)
        infos = np.zeros(16 * INFO_BYTES, dtype=np.uint8)
        mask = int(SampleState.Any | ViewState.Any | InstanceState.Any)
        got, end = [], time.monotonic() + timeout_s
        while len(got) < samples and time.monotonic() < end:
            n = c.takecdr(reader._ref, pointers.ctypes.data, 16, infos.ctypes.data, mask)
            if n < 0:
                return f"dds_takecdr returned {n}"
            for i in range(n):
                info = infos[i * INFO_BYTES:(i + 1) * INFO_BYTES]
                size = c.serdata_size(int(pointers[i]))
                data = np.zeros(max(size, 1), dtype=np.uint8)
                if 0 < size <= 64:
                    c.serdata_to_ser(int(pointers[i]), 0, size, data.ctypes.data)
                c.serdata_unref(int(pointers[i]))
                got.append((int(info[VALID_DATA]), int(info[SOURCE_TIMESTAMP:][:8].view(
                    np.int64)[0]), size, data))
            if n == 0:
                time.sleep(0.005)
        return _judge(got, samples)
    finally:
        for entity in (writer, reader, topic):
            entity.__del__()


def _judge(got, samples: int) -> str | None:
    if len(got) != samples:
        return f"{len(got)} of {samples} samples written came back through dds_takecdr"
    wall_ns = time.time_ns()
    stamps = []
    for k, (valid, stamp, size, data) in enumerate(got):
        value = data[4:12].view(np.float64)[0] if size >= 12 else None
        if valid != 1 or size != 12 or value != float(k) + 0.5:
            return (f"sample {k}: valid_data {valid}, {size} bytes, value {value} (expected "
                    f"1, 12, {k + 0.5}): dds_sample_info_t is not laid out as declared")
        if abs(stamp - wall_ns) > 60e9:
            return f"sample {k}: source timestamp {stamp} ns is not near now ({wall_ns} ns)"
        stamps.append(stamp)
    if stamps != sorted(stamps):
        return f"source timestamps {stamps} are not in the order written"
    return None
