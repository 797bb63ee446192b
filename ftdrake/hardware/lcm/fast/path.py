"""CompiledPath: the LCM station's per-message work done by the compiled loop (:mod:`.loop`)
whenever the station is in its ordinary state, by its Python path otherwise
(:class:`~ftdrake.hardware.fast.path.CompiledPathBase` says when and why).

What LCM adds: the station's connections must be liblcm ones no other station reads
(:class:`~.liblcm.LiblcmTransport`, opened from ``lcm.lcm_url`` and ``lcm.output_url``
with ``lcm.compiled_path`` true, by the station or by serve for it), and the joint states
``iiwa_status``. Not at all (said at start): a connection given to the station (an
``lcm.LCM``, a ``DrakeLcm``, another transport, another station's); liblcm not found;
another joint-state type (``panda_status``, ``robot_state``: the Python path reads them);
the payload output.
"""

from __future__ import annotations

import numpy as np

from ...fast.accept import K
from ...fast.path import BUDGET_S, CompiledPathBase  # noqa: F401 (BUDGET_S: the station's)
from ...messages import _FT_FINGERPRINT, _IIWA_FINGERPRINT, ContactState, encode_contact_state
from .codec import WRENCH_BYTES
from .liblcm import LiblcmTransport, load
from .loop import STOP_WAIT_FAILED, run

_SOURCES = {"wrench_compensated": 0, "wrench_contact": 1, "bias": 2}
#: Bytes of a channel name at most, with its terminating zero.
CHANNEL_BYTES = 256


class CompiledPath(CompiledPathBase):
    """The compiled per-message path of a
    :class:`~ftdrake.hardware.station.HardwareStation` (see the module and
    :class:`~ftdrake.hardware.fast.path.CompiledPathBase`)."""

    SECTION = "lcm"
    WARM_MODULE = "ftdrake.hardware.lcm.fast.loop"
    _loop = staticmethod(run)

    def _transport_problem(self) -> str | None:
        s, c = self.station, self.station.config
        loaded = load()
        if isinstance(loaded, str):
            return loaded
        if not (s.owns_lcm and isinstance(s.lcm, LiblcmTransport)
                and isinstance(s._sender, LiblcmTransport)):
            return ("the station's LCM connection was given to it (an lcm.LCM, a DrakeLcm, "
                    "a transport, another station's); the compiled path needs a liblcm "
                    "connection of its own, opened from lcm.lcm_url")
        if c.joint_state_type != "iiwa_status":
            return (f"lcm.joint_state_type is {c.joint_state_type!r}; the compiled path reads "
                    "iiwa_status")
        if len(s.lcm.handlers) != 2:
            return "the station reads channels beyond the joint states and wrenches"
        if any(port not in _SOURCES for port, _ in s._own_channel):
            return "the station publishes the payload estimate"
        if any(len(channel.encode()) >= CHANNEL_BYTES
               for channel in [ch for _, ch in s._own_channel] + [s._contact_channel]):
            return f"an output channel's name is {CHANNEL_BYTES} bytes or longer"
        self._c = s.lcm.c
        return None

    def _transport_ready(self) -> bool:
        return self.station.lcm.is_open  # closed: the Python path says so

    def _build_transport(self) -> None:
        s = self.station
        own = s._own_channel
        channels = np.zeros((max(1, len(own)), CHANNEL_BYTES), dtype=np.uint8)
        for i, (_, channel) in enumerate(own):
            name = channel.encode()
            channels[i, :len(name)] = np.frombuffer(name, dtype=np.uint8)
        contact = s._contact_channel.encode() + b"\0" if s._contact_out else b""
        template = encode_contact_state(ContactState(0.0, False, 0.0, False))
        self._outputs = (s._sender.lcm, channels[:len(own)],
                         np.array([_SOURCES[port] for port, _ in own], dtype=np.int64),
                         np.frombuffer(_FT_FINGERPRINT, dtype=np.uint8).copy(),
                         np.frombuffer(contact, dtype=np.uint8).copy(),
                         np.frombuffer(template, dtype=np.uint8).copy(), np.zeros(5))
        self._subs = np.array([0, 1], dtype=np.int64)  # the joint states, then the wrenches
        self._iiwa = np.frombuffer(_IIWA_FINGERPRINT, dtype=np.uint8).copy()
        self._buffers = (np.zeros(max(WRENCH_BYTES, len(template)), dtype=np.uint8),
                         self._spec, self._scratch)

    def _arguments(self, dry: bool) -> tuple:  # noqa: ARG002 (the same arguments when dry)
        """:func:`.loop.run`'s arguments after the C functions."""
        s = self.station
        joint_state, wrench, step_wrench, step_x = self._monitor_state()
        joint = (self._iiwa, self._x_new, self._limit, joint_state, self._scratch)
        ft = (self._outputs[3], self._wrench_new, wrench, joint_state, step_wrench, step_x,
              self._chain_out, self._scratch)
        return (s.lcm.lcm, s.lcm.inbox, s.lcm.inbox_bytes, self._subs, self._f, self._k,
                joint, ft, self._rings, self._chain, self._outputs, self._buffers)

    def _hand_back(self) -> int:
        """The inbox's entries the loop left, through the station's Python path (its LCM
        callbacks); the messages handled."""
        t = self.station.lcm
        if self._k[K["stop"]] == STOP_WAIT_FAILED:
            return t.handle(0)  # counts the failed waits, raising when they go on
        if not t.inbox[0]:
            return 0
        handled = t.dispatch(int(self._k[K["handback"]]))
        self.handed_back += handled
        return handled

    def _write_failed(self, count: int) -> None:
        raise OSError(f"LCM: {count} publications of the station's outputs failed in the "
                      "compiled loop")
