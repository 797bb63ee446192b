"""One small interface over an LCM connection: subscribe, publish, handle, with no message lost
in the library.

Why not ``pydrake.lcm.DrakeLcm`` for the live streams: LCM keeps at most 30 undelivered
messages per subscription and drops the rest silently; DrakeLcm does not expose
``set_queue_capacity`` to Python, so a subscriber that is descheduled for 30 ms on a busy
machine loses 1 kHz messages (docs, Derivations). The
``lcm`` package's subscriptions take a capacity; :func:`open_lcm` sets it to
`QUEUE_CAPACITY` (≈ 10 s of one 1 kHz stream). A DrakeLcm is still accepted (tests, users'
own diagrams) through :class:`DrakeTransport`.
"""

from __future__ import annotations

from collections.abc import Callable

from ..errors import ConfigError

#: Messages LCM may hold per subscription before it drops (LCM's default is 30).
QUEUE_CAPACITY = 10_000


class LcmTransport:
    """An ``lcm.LCM`` with callbacks taking the message bytes."""

    def __init__(self, lc):
        self.lc = lc
        self._subscriptions = []
        self._errors = 0  # consecutive failed waits

    def subscribe(self, channel: str, handler: Callable[[bytes], None]) -> None:
        sub = self.lc.subscribe(channel, lambda _channel, data: handler(data))
        sub.set_queue_capacity(QUEUE_CAPACITY)
        self._subscriptions.append(sub)

    def publish(self, channel: str, data: bytes) -> None:
        self.lc.publish(channel, data)

    def start_receiving(self) -> None:
        """Starts the provider's receiving now (udpm://: its receive thread), not at the
        first wait."""
        self.lc.fileno()

    def handle(self, timeout_ms: int = 0) -> int:
        """Handles every pending message, waiting up to `timeout_ms` for the first one.
        Returns how many were handled."""
        handled = 0
        try:
            while self.lc.handle_timeout(int(timeout_ms) if handled == 0 else 0) > 0:
                handled += 1
        except OSError:  # -1: a signal interrupted the wait (Ctrl-C), or a socket error
            self._errors += 1
            if self._errors > 100:  # not a signal: it keeps failing
                raise
            return handled
        self._errors = 0
        return handled


class DrakeTransport:
    """A ``pydrake.lcm.DrakeLcm`` (LCM's default queue capacity of 30 per subscription)."""

    def __init__(self, drake_lcm):
        self.lc = drake_lcm

    def subscribe(self, channel: str, handler: Callable[[bytes], None]) -> None:
        self.lc.Subscribe(channel, handler)

    def publish(self, channel: str, data: bytes) -> None:
        self.lc.Publish(channel, data)

    def start_receiving(self) -> None:
        """DrakeLcm receives on its own once subscribed."""

    def handle(self, timeout_ms: int = 0) -> int:
        return self.lc.HandleSubscriptions(int(timeout_ms))


def open_lcm(url_or_transport, where: str = "hardware.lcm_url", native: bool = False):
    """A transport from an LCM URL (``udpm://239.255.76.67:7667?ttl=0``, ``memq://``), an
    ``lcm.LCM``, a ``DrakeLcm`` or a transport. A URL LCM cannot open raises ConfigError
    naming `where`. `native`: a URL is opened by liblcm's C API
    (:class:`~ftdrake.hardware.lcm.fast.liblcm.LiblcmTransport`, which the station's
    compiled path reads too) where liblcm can be loaded, else by the ``lcm`` package."""
    if isinstance(url_or_transport, (LcmTransport, DrakeTransport)) or hasattr(
            url_or_transport, "dispatch"):  # ours (a LiblcmTransport)
        return url_or_transport
    if isinstance(url_or_transport, str) and native:
        from .lcm.fast import liblcm  # noqa: PLC0415 (numba only for the compiled path)

        if not isinstance(liblcm.load(), str):
            return liblcm.LiblcmTransport(url_or_transport, where, QUEUE_CAPACITY)
    if isinstance(url_or_transport, str):
        import lcm  # noqa: PLC0415 (the lcm package only for a live connection)

        try:
            return LcmTransport(lcm.LCM(url_or_transport))
        except (RuntimeError, OSError, ValueError) as e:
            raise ConfigError(f"{where}: cannot open LCM at {url_or_transport!r} ({e}; "
                              "see the LCM URL forms udpm://, memq://)") from None
    if hasattr(url_or_transport, "HandleSubscriptions"):
        return DrakeTransport(url_or_transport)
    if hasattr(url_or_transport, "handle_timeout"):
        return LcmTransport(url_or_transport)
    raise TypeError(f"not an LCM connection: {type(url_or_transport).__name__}")
