"""liblcm's C functions, and the station's LCM connection over them (:class:`LiblcmTransport`),
which both the station's Python path and its compiled loop read.

Why liblcm's own C API: the compiled loop (:mod:`.loop`) waits, takes and publishes without
the interpreter, so it cannot go through the ``lcm`` package's Python object; and both
paths must read one queue, so that no message is read twice or missed when the station
switches between them. The ``lcm`` wheel ships ``liblcm.so`` and its header
(``include/lcm/lcm.h``, LCM 1.5); the declarations below are that header's:

* ``lcm_t *lcm_create(const char *url)``, ``void lcm_destroy(lcm_t *)``,
  ``int lcm_get_fileno(lcm_t *)`` (starts the ``udpm://`` receive thread);
* ``lcm_subscription_t *lcm_subscribe(lcm_t *, const char *channel, handler, void *user)``,
  ``int lcm_subscription_set_queue_capacity(lcm_subscription_t *, int)``;
* ``int lcm_handle_timeout(lcm_t *, int ms)``: waits up to `ms` for one message and
  dispatches it to every subscription whose channel (a regular expression, anchored) it
  matches; > 0 when it did, 0 on timeout, < 0 on an error;
* ``int lcm_publish(lcm_t *, const char *channel, const void *data, unsigned int size)``;
* the handler gets ``const lcm_recv_buf_t *`` = ``{void *data; uint32_t data_size;
  int64_t recv_utime; lcm_t *lcm}`` (offsets 0, 8, 16, 24 on a 64-bit platform).

The handler is :func:`on_message`, compiled (a numba ``cfunc``): it copies each message into
the connection's inbox (an int64 table of entries and a byte buffer, :data:`ENTRIES`,
:data:`INBOX_BYTES`); whoever called ``lcm_handle_timeout`` then reads the inbox: the
Python path hands each entry's bytes to the subscription's handler, as the ``lcm``
package's subscriptions do, and the compiled loop reads them itself. LCM keeps at most the
subscription's queue capacity of undelivered messages (`capacity`; the station's
:func:`~ftdrake.hardware.transport.open_lcm` sets the Python transport's).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import weakref
from ctypes import c_char_p, c_int32, c_uint32, c_uint64
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np
from numba import carray, types
from numba.extending import intrinsic

from ....errors import ConfigError

#: Entries the inbox holds between two reads (one dispatch fills one per matching
#: subscription).
ENTRIES = 16
#: Bytes the inbox holds between two reads; a longer message is kept cut short and said.
INBOX_BYTES = 1 << 20
#: The inbox table: [count, bytes used, entries lost] then per entry (subscription, size,
#: bytes kept, recv_utime µs, offset).
HEAD, FIELDS = 3, 5
INBOX_INTS = HEAD + ENTRIES * FIELDS


class LiblcmC(NamedTuple):
    """The functions the compiled loop calls (pointers as uint64), and time.monotonic's
    clock_gettime."""

    handle_timeout: object
    publish: object
    clock_gettime: object


_loaded: tuple | str | None = None


def _library_path() -> str | None:
    """liblcm.so of the installed ``lcm`` wheel (``<site-packages>/lib``), else the
    system's."""
    try:
        import lcm  # noqa: PLC0415
    except ImportError:
        return None
    for name in ("liblcm.so.1", "liblcm.so", "liblcm.dylib"):
        candidate = Path(lcm.__file__).resolve().parent.parent / "lib" / name
        if candidate.exists():
            return str(candidate)
    return ctypes.util.find_library("lcm")


def _function(lib, name, result, *arguments):
    function = lib[name]  # a function object of its own (getattr's is shared)
    function.restype, function.argtypes = result, list(arguments)
    return function


def load():
    """(LiblcmC, the other functions by name), or why liblcm cannot be had (a sentence);
    loaded once."""
    global _loaded
    if _loaded is None:
        path = _library_path()
        if path is None:
            _loaded = "liblcm was not found (the lcm package's lib/liblcm.so)"
            return _loaded
        try:
            lib, libc = ctypes.CDLL(path), ctypes.CDLL(None)
            c = LiblcmC(_function(lib, "lcm_handle_timeout", c_int32, c_uint64, c_int32),
                        _function(lib, "lcm_publish", c_int32, c_uint64, c_uint64, c_uint64,
                                  c_uint32),
                        _function(libc, "clock_gettime", c_int32, c_int32, c_uint64))
            other = {
                "create": _function(lib, "lcm_create", c_uint64, c_char_p),
                "destroy": _function(lib, "lcm_destroy", None, c_uint64),
                "fileno": _function(lib, "lcm_get_fileno", c_int32, c_uint64),
                "subscribe": _function(lib, "lcm_subscribe", c_uint64, c_uint64, c_char_p,
                                       c_uint64, c_uint64),
                "capacity": _function(lib, "lcm_subscription_set_queue_capacity", c_int32,
                                      c_uint64, c_int32),
                "publish": _function(lib, "lcm_publish", c_int32, c_uint64, c_char_p, c_char_p,
                                     c_uint32)}
        except (OSError, AttributeError) as e:
            _loaded = f"liblcm could not be loaded from {path} ({e})"
            return _loaded
        _loaded = (c, other)
    return _loaded


@intrinsic
def _as_pointer(typingctx, address):  # noqa: ARG001 (numba's intrinsic signature)
    """An integer address as a void pointer (for carray)."""
    def codegen(context, builder, signature, args):  # noqa: ARG001
        return builder.inttoptr(args[0], context.get_value_type(types.voidptr))
    return types.voidptr(address), codegen


@numba.cfunc(types.void(types.voidptr, types.voidptr, types.voidptr), cache=True)
def on_message(rbuf, channel, user):  # noqa: ARG001 (liblcm's handler signature)
    """liblcm's handler: the message appended to the inbox `user` names ([subscription
    index, inbox table address, inbox bytes address]); cut short when the bytes are full,
    counted as lost when the table is."""
    u = carray(user, 3, np.int64)
    inbox = carray(_as_pointer(u[1]), INBOX_INTS, np.int64)
    count, used = inbox[0], inbox[1]
    if count >= ENTRIES:
        inbox[2] += 1
        return
    size = np.int64(carray(rbuf, 4, np.uint32)[2])
    kept = min(size, INBOX_BYTES - used)
    head = carray(rbuf, 3, np.int64)
    e = HEAD + count * FIELDS
    inbox[e], inbox[e + 1], inbox[e + 2], inbox[e + 3], inbox[e + 4] = (
        u[0], size, kept, head[2], used)
    if kept > 0:
        carray(_as_pointer(u[2] + used), kept, np.uint8)[:] = carray(
            _as_pointer(head[0]), kept, np.uint8)
    inbox[0], inbox[1] = count + 1, used + kept


class LiblcmTransport:
    """An LCM connection by liblcm's C API (:func:`load`): the transport interface of
    :class:`~ftdrake.hardware.transport.LcmTransport` (subscribe, publish, start_receiving,
    handle), with the inbox the compiled loop reads. `url` an LCM URL; ConfigError naming
    `where` when liblcm cannot open it. `capacity`: messages LCM may hold per subscription
    before it drops (LCM's default is 30)."""

    def __init__(self, url: str, where: str = "hardware.lcm_url", capacity: int = 30):
        loaded = load()
        if isinstance(loaded, str):
            raise RuntimeError(loaded)  # noqa: TRY004 (why liblcm cannot be had)
        self.c, self._f = loaded
        self.url, self.capacity = url, int(capacity)
        self.lcm = int(self._f["create"](url.encode()) or 0)
        if not self.lcm:
            raise ConfigError(f"{where}: cannot open LCM at {url!r} (see the LCM URL forms "
                              "udpm://, memq://)")
        self._finalizer = weakref.finalize(self, self._f["destroy"], self.lcm)
        self.inbox = np.zeros(INBOX_INTS, dtype=np.int64)
        self.inbox_bytes = np.zeros(INBOX_BYTES, dtype=np.uint8)
        self.channels: list[str] = []
        self.handlers: list = []
        self._users: list[np.ndarray] = []  # each subscription's `user` array, kept alive
        self._errors = 0
        self.cut_short = self.lost = 0
        self.on_warning = None  # called with a sentence when a message was cut short or lost
        self.owner = None  # the station whose compiled path reads this connection

    def subscribe(self, channel: str, handler) -> None:
        """`handler(bytes)` for each message on `channel` (LCM's channel regex, as the lcm
        package's)."""
        user = np.array([len(self.handlers), self.inbox.ctypes.data,
                         self.inbox_bytes.ctypes.data], dtype=np.int64)
        sub = self._f["subscribe"](self._open(), channel.encode(), on_message.address,
                                   user.ctypes.data)
        if not sub:
            raise ConfigError(f"cannot subscribe to the LCM channel {channel!r}")
        self._f["capacity"](sub, self.capacity)
        self._users.append(user)
        self.channels.append(channel)
        self.handlers.append(handler)

    def publish(self, channel: str, data: bytes) -> None:
        if self._f["publish"](self._open(), channel.encode(), data, len(data)) < 0:
            raise OSError(f"LCM: publishing on {channel!r} failed")

    def start_receiving(self) -> None:
        """Starts the provider's receiving now (udpm://: its receive thread)."""
        self._f["fileno"](self._open())

    def handle(self, timeout_ms: int = 0) -> int:
        """Handles every pending message, waiting up to `timeout_ms` for the first one.
        Returns how many were handled."""
        handled = 0
        while True:
            result = self.c.handle_timeout(self._open(),
                                           int(timeout_ms) if handled == 0 else 0)
            if result < 0:  # a signal interrupted the wait (Ctrl-C), or a socket error
                self._errors += 1
                if self._errors > 100:
                    raise OSError(f"LCM at {self.url}: waiting for messages failed "
                                  f"{self._errors} times in a row")
                return handled
            self._errors = 0
            if result == 0:
                return handled
            handled += self.dispatch(0)

    def dispatch(self, first: int) -> int:
        """The inbox's entries from `first` on handed to their subscriptions' handlers, in
        order; the inbox emptied. Returns how many."""
        inbox, data = self.inbox, self.inbox_bytes
        count = int(inbox[0])
        self._say_losses()
        try:
            for i in range(first, count):
                sub, size, kept, _, offset = inbox[HEAD + i * FIELDS:HEAD + (i + 1) * FIELDS]
                if kept < size:
                    self.cut_short += 1
                    self._warn(f"a message of {size} bytes on the LCM channel "
                               f"{self.channels[sub]!r} was cut to the station's "
                               f"{INBOX_BYTES} bytes; it is not the configured type")
                self.handlers[sub](data[offset:offset + kept].tobytes())
        finally:  # emptied even when a handler raised: no entry is handed over twice
            inbox[0] = inbox[1] = 0
        return count - first

    def _say_losses(self) -> None:
        lost = int(self.inbox[2])
        if lost:
            self.inbox[2] = 0
            self.lost += lost
            self._warn(f"{lost} LCM messages matched more subscriptions than the inbox "
                       f"holds ({ENTRIES}) and were not handled")

    def _warn(self, sentence: str) -> None:
        if self.on_warning is not None:
            self.on_warning(sentence)

    def close(self) -> None:
        """Destroys the connection (its receive thread stops); using it after is an error,
        not a call into freed memory."""
        self._finalizer()

    @property
    def is_open(self) -> bool:
        return self._finalizer.alive

    def _open(self) -> int:
        """The lcm_t pointer; RuntimeError once closed."""
        if not self.is_open:
            raise RuntimeError(f"the LCM connection to {self.url} is closed")
        return self.lcm
