"""CompiledPath: the ROS 2 station's per-message work done by the compiled loop
(:mod:`.loop`) whenever the station is in its ordinary state, by its Python path otherwise
(:class:`~ftdrake.hardware.fast.path.CompiledPathBase` says when and why).

What ROS 2 adds: the loop runs only with the joint name list known and nothing held by the
node, and with wrenches in a frame every output writer can write packed. Not at all (said
at start): Cyclone's C declarations do not hold (:func:`.cyclone.self_test`); a reorder
window; topics beyond the joint states and wrenches.
"""

from __future__ import annotations

import time

import numpy as np

from ...fast.accept import K
from ...fast.path import BUDGET_S, CompiledPathBase  # noqa: F401 (BUDGET_S: the station's)
from . import cyclone
from .cdr import names_cdr
from .loop import ITEMS, TAKE, run

#: bytes of the largest message the loop reads itself (larger ones go to Python).
MAX_MESSAGE = 65536
_SOURCES = {"wrench_compensated": 0, "wrench_contact": 1, "bias": 2, "contact": 3,
            "contact_force": 4}


class CompiledPath(CompiledPathBase):
    """The compiled per-message path of a :class:`~ftdrake.hardware.ros2.station.Ros2Station`
    (see the module and :class:`~ftdrake.hardware.fast.path.CompiledPathBase`)."""

    SECTION = "ros2"
    WARM_MODULE = "ftdrake.hardware.ros2.fast.loop"
    _loop = staticmethod(run)

    def _transport_problem(self) -> str | None:
        s, c = self.station, self.station.config
        if c.reorder_window_s > 0:
            return "ros2.reorder_window_s holds messages (> 0)"
        if len(s.node._handlers) != 2:
            return "the station reads topics beyond the joint states and wrenches"
        loaded = cyclone.load()
        if isinstance(loaded, str):
            return loaded
        problem = cyclone.self_test(s.node.participant, loaded)
        if problem is not None:
            return f"Cyclone DDS's C declarations do not hold: {problem}"
        self._c = loaded
        return None

    def _transport_ready(self) -> bool:
        s = self.station
        return not (s.node._pending or s._order[1] is None or s._header is None
                    or self._outputs_for(s._header.frame_id) is None)

    def _build_transport(self) -> None:
        from cyclonedds.core import InstanceState, SampleState, ViewState  # noqa: PLC0415

        s = self.station
        readers = [reader for reader, *_ in s.node._handlers]
        self._handlers = {k: (kind, handler, read)
                          for k, (_, kind, handler, _, read) in enumerate(s.node._handlers)}
        self._readers = np.array([r._ref for r in readers], dtype=np.int32)
        self._mask = int(SampleState.Any | ViewState.Any | InstanceState.Any)
        self._items = (np.zeros(ITEMS, dtype=np.uint64), np.zeros(ITEMS, dtype=np.int64),
                       np.zeros(ITEMS, dtype=np.int8))
        self._take = (np.zeros(TAKE, dtype=np.uint64),
                      np.zeros(TAKE * cyclone.INFO_BYTES, dtype=np.uint8),
                      np.zeros(MAX_MESSAGE, dtype=np.uint8))
        self._buffers = (np.zeros(MAX_MESSAGE, dtype=np.uint8), np.zeros(2, dtype=np.uint64),
                         self._spec)
        self._names = (None, None)  # (names list, (CDR bytes, order, values scratch))
        self._frames: dict[str, tuple | None] = {}
        self._sertypes = {}

    def _write_failed(self, count: int) -> None:
        from cyclonedds.core import DDSException  # noqa: PLC0415 (ROS 2 only)

        raise DDSException(-1, f"{count} writes of the station's outputs failed in the "
                           "compiled loop")

    def _outputs_for(self, frame_id: str):
        """(expected frame bytes, the outputs tuple) for wrenches in `frame_id`; None when a
        writer cannot write them packed (then the Python path writes them)."""
        if frame_id in self._frames:
            return self._frames[frame_id]
        s = self.station
        writers, sertypes, heads, sources = [], [], [], []
        for name, out in s._wrench_out:
            packing = out._struct(frame_id)
            if packing is None:
                self._frames[frame_id] = None
                return None
            writers.append(out.writer)
            heads.append(np.frombuffer(packing[1], dtype=np.uint8))
            sources.append(_SOURCES[name])
        for name, out in s._value_out.items():
            if not out.packed:
                self._frames[frame_id] = None
                return None
            writers.append(out.writer)
            heads.append(np.frombuffer(out._head, dtype=np.uint8))
            sources.append(_SOURCES[name])
        for writer in writers:
            if writer._ref not in self._sertypes:
                self._sertypes[writer._ref] = cyclone.sertype_of(writer._ref)
            sertypes.append(self._sertypes[writer._ref])
        frame = np.frombuffer(frame_id.encode("utf-8") + b"\0", dtype=np.uint8).copy()
        found = (frame, (np.array([w._ref for w in writers], dtype=np.int32),
                  np.array(sertypes, dtype=np.uint64),
                  np.array(heads, dtype=np.uint8).reshape(len(heads), 4),
                  np.array(sources, dtype=np.int64), bool(s._value_out)))
        self._frames[frame_id] = found
        return found

    def _names_for(self):
        names, order = self.station._order
        if self._names[0] is not names:
            self._names = (names, (names_cdr(names), np.asarray(order, dtype=np.int64),
                                   np.zeros(len(names))))
        return self._names[1]

    def _arguments(self, dry: bool) -> tuple:
        """:func:`.loop.run`'s arguments after the C functions."""
        s = self.station
        frame, outputs = self._outputs_for("" if dry else s._header.frame_id)
        names, order, values = self._names_for_or_dummy(dry)
        joint_state, wrench, step_wrench, step_x = self._monitor_state()
        joint = (names, order, self._x_new, values, self._limit, self._scratch, joint_state)
        ft = (frame, self._wrench_new, self._scratch, wrench, joint_state, step_wrench,
              step_x, self._chain_out)
        return (s.node._waitset._ref, self._readers, self._mask, self._items, self._f,
                self._k, joint, ft, self._rings, self._chain, outputs, self._buffers,
                self._take)

    def _names_for_or_dummy(self, dry: bool):
        if dry:
            return (np.zeros(4, dtype=np.uint8), np.arange(self.station.n_joints),
                    np.zeros(self.station.n_joints))
        return self._names_for()

    def _hand_back(self) -> int:
        """The samples the loop left (still referenced): their bytes read into the node's
        pending list, in order, as its own take would have, then the node's Python path
        run on them; the messages it handled."""
        count = int(self._k[K["handback"]])
        if not count:
            return 0
        c, node = self._c, self.station.node
        ptrs, stamps, streams = self._items
        now = time.monotonic()
        for i in range(count):
            pointer = int(ptrs[i])
            size = c.serdata_size(pointer)
            data = bytearray(size)
            c.serdata_to_ser(pointer, 0, size, (np.frombuffer(data, dtype=np.uint8)
                                                .ctypes.data))
            c.serdata_unref(pointer)
            kind, handler, read = self._handlers[int(streams[i])]
            node.hold(int(stamps[i]), bytes(data), kind, handler, read, now)
        self.handed_back += count
        return node.spin(0)
