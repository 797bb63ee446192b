"""The LCM station's compiled per-message path against its Python path, over LCM's udpm on
loopback (ttl=0) in one process: two stations read the same driver's messages, one with
``compiled_path`` on (liblcm's own connection, the compiled loop), one off (the ``lcm``
package's connection, the Python callbacks), and must publish the same messages (bytes for
bytes) and count the same, through ordinary messages and unusual ones (NaN, a stamp going
back, lost samples, a joint state beyond its bounds, a message of another type, a
contact). The path's parts: its LCM codec against ftdrake.hardware.messages, liblcm's
connection (order, a message cut short said), and why it does not run where it cannot."""

import os

import lcm
import numpy as np
import pytest

from ftdrake import ChainConfig, ConfigError
from ftdrake.hardware.config import HardwareConfig
from ftdrake.hardware.fast import path as fast_path
from ftdrake.hardware.lcm.fast import codec, liblcm
from ftdrake.hardware.messages import (
    _FT_FINGERPRINT,
    _IIWA_FINGERPRINT,
    ContactState,
    decode_contact_state,
    decode_joint_state,
    decode_wrench,
    encode_contact_state,
    encode_joint_state,
    encode_wrench,
)
from ftdrake.hardware.station import HardwareStation
from tests.helpers import assert_twins_count_alike, fused_forest, twin_stream, wait_for

N = 7
PORT = 7700 + os.getpid() % 200
URL = f"udpm://239.255.76.{120 + os.getpid() % 100}:{PORT}?ttl=0"
WRENCHES = ("wrench_compensated", "wrench_contact", "bias")
pytestmark = pytest.mark.skipif(isinstance(liblcm.load(), str), reason="liblcm not found")


def station(model, compiled: bool, chain=None, **config):
    """A station on the real clock (the compiled path's), its own output channels on the
    inputs' URL (so it also receives its own outputs, as by default)."""
    config = HardwareConfig(lcm_url=URL, compiled_path=compiled,
                            output_prefix=f"FT{os.getpid()}_{int(compiled)}_",
                            sensor_timeout_s=5.0, joint_state_timeout_s=5.0,
                            max_backlog_s=100.0, **config)
    dut = HardwareStation(config, model, chain or ChainConfig())
    dut.compiled.wait()
    return dut


class Twin:
    """Two stations (compiled path on / off) on one driver's channels, a listener on both."""

    def __init__(self, model, chain):
        self.on, self.off = station(model, True, chain), station(model, False, chain)
        self.driver = lcm.LCM(URL)
        self.listener = lcm.LCM(URL)
        self.got = {}
        for dut in (self.on, self.off):
            channels = [dut.config.output_channel(p) for p in WRENCHES if dut.has_output(p)]
            for channel in [*channels, dut.config.output_channel("contact")]:
                got = self.got[channel] = []
                sub = self.listener.subscribe(channel, lambda _c, d, got=got: got.append(d))
                sub.set_queue_capacity(10_000)
        self.sent = 0

    def write(self, t, q, v, w, joint=True, ft=True, ft_bytes=None):
        """A joint state stamped 0.2 ms before the wrench (brought forward to it) and the
        wrench stamped `t`."""
        if joint:
            self.driver.publish("IIWA_STATUS",
                                encode_joint_state("iiwa_status", t - 0.0002, q, v))
        if ft:
            self.driver.publish("FT_SENSOR", ft_bytes or encode_wrench(t, w))
        self.sent += joint + ft

    def spin_all(self):
        for dut in (self.on, self.off):
            wait_for(lambda dut=dut: (dut.spin_once(1), sum(dut.monitor.received.values()))[1]
                     >= self.sent, "the stations to receive")
        self.listen()

    def listen(self):
        while self.listener.handle_timeout(0) > 0:
            pass

    def caught_up(self):
        def done():
            self.listen()
            return all(len(self.got[dut.config.output_channel("wrench_contact")])
                       == dut.published for dut in (self.on, self.off))
        wait_for(done, "the listener")

    def outputs(self, dut, port):
        return self.got[dut.config.output_channel(port)]

    def close(self):
        for dut in (self.on, self.off):
            dut.close()


def drive(twin):
    """The twin stream (helpers.twin_stream), with a joint state on the wrench channel, a
    joint state in degrees and one going back."""
    for k, t, q, v, w in twin_stream():
        if k == 1300:  # another type on the wrench channel
            twin.write(t, q, v, w, ft_bytes=encode_joint_state("iiwa_status", t, q, v))
            continue
        twin.write(t, q, v, w)
        if k == 1350:  # a joint state in degrees, between two good ones
            twin.write(t + 0.0005, np.degrees(q) + 400.0, v, w, ft=False)
        if k == 1150:
            twin.write(t - 0.0015, q, v, w, ft=False)  # a stamp going back
        if k % 10 == 9:  # the listener kept draining: LCM's socket buffers are small
            twin.spin_all()
    twin.spin_all()


@pytest.mark.parametrize("tracker", [True, False], ids=["tracker on", "tracker off"])
def test_the_compiled_path_publishes_and_counts_as_the_python_path(tracker):
    chain = ChainConfig()
    chain.bias_tracker.enabled = tracker
    twin = Twin(fused_forest(), chain)
    try:
        assert twin.on.compiled.why_not is None, twin.on.compiled.why_not
        assert twin.off.compiled.why_not == "lcm.compiled_path is false"
        drive(twin)
        twin.caught_up()
        on, off = twin.on.summary(), twin.off.summary()
        assert_twins_count_alike(on, off)
        # Five lost, and the one replaced by a message of another type.
        assert on["load"]["lost_ft"] == off["load"]["lost_ft"] == 6
        assert on["rejected"] == {"not_finite": 1, "out_of_order": 1, "joint_range": 1,
                                  "wrong_type": 1}
        assert on["processed"] > 1650
        for port in WRENCHES:
            if twin.on.has_output(port):
                assert twin.outputs(twin.on, port) == twin.outputs(twin.off, port), port
        # The contact states, bytes for bytes, but for the stamp of the one answering the
        # message of another type: it has none, so it is stamped on the wall clock.
        sent = {round(0.001 * (k + 1), 6) for k in range(1700)}
        states = {}
        for dut in (twin.on, twin.off):
            states[dut] = [decode_contact_state(d) for d in twin.outputs(dut, "contact")]
            assert sum(round(s.t, 6) not in sent for s in states[dut]) == 1
        assert [s if round(s.t, 6) in sent else s[1:] for s in states[twin.on]] == [
            s if round(s.t, 6) in sent else s[1:] for s in states[twin.off]]
        contact = [s.contact for s in states[twin.on]]
        assert any(contact) and not all(contact)
        compiled = on["compiled_path"]
        # Most messages went through the compiled loop; the unusual ones went back.
        assert compiled["used"] and compiled["calls"] > 10 and compiled["handed_back"] >= 5
        assert off["compiled_path"]["calls"] == 0
        assert twin.on.compiled.loop_messages > 500
        # Once closed, the station says so rather than reading freed memory.
        twin.on.close()
        with pytest.raises(RuntimeError, match="is closed"):
            twin.on.spin_once(1)
    finally:
        twin.close()


def test_the_codec_reads_and_writes_the_bytes_of_the_python_codec():
    rng = np.random.default_rng(4)
    scratch = np.zeros(8, dtype=np.uint8)
    ft = np.frombuffer(_FT_FINGERPRINT, dtype=np.uint8)
    iiwa = np.frombuffer(_IIWA_FINGERPRINT, dtype=np.uint8)
    for t in (0.001, 12.3456785, 1.7e9 + 0.0005):
        w = rng.normal(size=6) * 100
        data = np.frombuffer(encode_wrench(t, w), dtype=np.uint8)
        got = np.zeros(6)
        read, t_read = codec.read_wrench(data, len(data), ft, got, scratch)
        expected = decode_wrench(data.tobytes())
        assert read and t_read == expected.t
        np.testing.assert_array_equal(got, expected.wrench)
        out = np.zeros(256, dtype=np.uint8)
        size = codec.wrench_bytes(out, ft, t, w, scratch)
        assert out[:size].tobytes() == encode_wrench(t, w)
        q, v = rng.normal(size=N), rng.normal(size=N)
        data = np.frombuffer(encode_joint_state("iiwa_status", t, q, v), dtype=np.uint8)
        x = np.zeros(2 * N)
        read, t_read = codec.read_iiwa_status(data, len(data), iiwa, x, scratch)
        sample = decode_joint_state("iiwa_status", data.tobytes())
        assert read and t_read == sample.t
        np.testing.assert_array_equal(x, np.r_[sample.q, sample.v])
        # Cut short, another joint count or another type: not read here (Python's).
        assert not codec.read_iiwa_status(data, len(data) - 1, iiwa, x, scratch)[0]
        assert not codec.read_iiwa_status(data, len(data), iiwa, np.zeros(12), scratch)[0]
        assert not codec.read_wrench(data, len(data), ft, got, scratch)[0]
        template = np.frombuffer(encode_contact_state(ContactState(0.0, False, 0.0, False)),
                                 dtype=np.uint8)
        values = np.array([1.0, 31.5, 0.0, 1.0, 0.0])
        size = codec.contact_bytes(out, template, t, values, scratch)
        assert out[:size].tobytes() == encode_contact_state(
            ContactState(t, True, 31.5, False, True, False))


def test_the_connection_hands_messages_over_in_order_and_says_one_cut_short():
    warnings = []
    t = liblcm.LiblcmTransport("memq://")
    t.on_warning = warnings.append
    got = []
    t.subscribe("A", lambda d: got.append(("A", d)))
    t.subscribe("B", lambda d: got.append(("B", d)))
    for i in range(5):
        t.publish("A" if i % 2 else "B", bytes([i, 7]))
    t.publish("C", b"not subscribed")
    t.publish("A", bytes(liblcm.INBOX_BYTES + 10))
    assert t.handle(10) == 6
    assert got[:5] == [("B" if i % 2 == 0 else "A", bytes([i, 7])) for i in range(5)]
    assert got[5] == ("A", bytes(liblcm.INBOX_BYTES))
    assert t.cut_short == 1 and "cut to the station's" in warnings[0]
    t.close()
    with pytest.raises(RuntimeError, match="is closed"):
        t.handle(0)


def test_where_the_compiled_path_cannot_run_it_says_why():
    model = fused_forest()
    given = HardwareStation(HardwareConfig(lcm_url="memq://"), model, ChainConfig(),
                            lcm.LCM("memq://"))
    assert "was given to it" in given.compiled.why_not
    own = HardwareStation(HardwareConfig(lcm_url="memq://"), model, ChainConfig())
    assert own.compiled.why_not is None
    # Given another station's own connection: still not its own.
    shared = HardwareStation(HardwareConfig(lcm_url="memq://", output_prefix="OTHER_"), model,
                             ChainConfig(), own.lcm)
    assert "was given to it" in shared.compiled.why_not
    # Closing it leaves the connection to the station that owns it.
    shared.close()
    got = []
    own.lcm.subscribe("PROBE", got.append)
    own.lcm.publish("PROBE", b"still open")
    assert own.lcm.handle(10) == 1 and got == [b"still open"]
    # Driven through the diagram after it was built: the compiled path steps aside.
    own.use_diagram()
    assert not own.compiled.ready()
    assert own.compiled.why_not == "the chain is driven through the Drake diagram"
    panda = HardwareStation(HardwareConfig(lcm_url="memq://", joint_state_type="panda_status"),
                            model, ChainConfig())
    assert "panda_status" in panda.compiled.why_not
    with pytest.raises(ConfigError, match=r"lcm\.compiled_path"):
        HardwareConfig(compiled_path="yes").validate("lcm")
    for dut in (given, panda, own):
        dut.close()


def test_stations_of_one_kind_share_one_compile(monkeypatch):
    """Two stations whose loops have the same types start one compiling process, not two;
    both load the loop once it is done (here a process that compiles nothing: the loop is
    then compiled, or found in numba's cache, by the first to load it)."""
    started = []
    popen = fast_path.subprocess.Popen
    monkeypatch.setattr(fast_path, "_in_cache", lambda *_: False)
    monkeypatch.setattr(fast_path.sys, "executable", "/bin/true")
    monkeypatch.setattr(fast_path.subprocess, "Popen",
                        lambda *a, **k: started.append(a) or popen(*a, **k))
    model = fused_forest()
    duts = [HardwareStation(HardwareConfig(lcm_url="memq://"), model, ChainConfig())
            for _ in range(2)]
    try:
        assert len(started) == 1
        assert all(dut.compiled.wait(60) for dut in duts)
        assert not fast_path._Compile.running
    finally:
        for dut in duts:
            dut.close()


def test_a_handler_that_raises_does_not_leave_its_message_to_be_handed_over_again():
    t = liblcm.LiblcmTransport("memq://")
    got = []

    def handler(data):
        got.append(data)
        if data == b"bad":
            raise ValueError("the station's own error")

    t.subscribe("A", handler)
    t.publish("A", b"bad")
    with pytest.raises(ValueError, match="own error"):
        t.handle(10)
    t.publish("A", b"good")
    assert t.handle(10) == 1
    assert got == [b"bad", b"good"]
    t.close()


def test_without_liblcm_the_station_serves_in_python_and_says_why(monkeypatch):
    monkeypatch.setattr(liblcm, "_loaded", "liblcm was not found (a test)")
    dut = HardwareStation(HardwareConfig(lcm_url="memq://"), fused_forest(), ChainConfig())
    assert dut.compiled.why_not == "liblcm was not found (a test)"
    assert not isinstance(dut.lcm, liblcm.LiblcmTransport)  # the lcm package's
    dut.close()
