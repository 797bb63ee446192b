"""The transports' receive threads yield to the chain's thread (hardware/threads.py), a
station keeps every thread of the process on the CPUs of ``cpu_affinity``, and an LCM
station's outputs go on a connection of their own (``output_url``).

Over UDP multicast with ttl=0 (it stays on this machine); skipped where that or
``SCHED_BATCH`` (Linux) is unavailable."""

import os
import threading

import numpy as np
import pytest

from ftdrake import RandomForestCompensator
from ftdrake.errors import ConfigError
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import decode_wrench, encode_joint_state, encode_wrench
from ftdrake.hardware.station import HardwareStation
from ftdrake.hardware.threads import NewThreads, pin_process, thread_ids, usable_cpus

lcm = pytest.importorskip("lcm")
BATCH = getattr(os, "SCHED_BATCH", None)
pytestmark = pytest.mark.skipif(BATCH is None, reason="SCHED_BATCH is Linux's")
PORT = 7300 + os.getpid() % 200  # distinct between concurrent test runs
GROUP = f"239.255.76.{67 + os.getpid() % 100}"
N = 7


def _url(port: int) -> str:
    return f"udpm://{GROUP}:{port}?ttl=0"


def _model():
    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, size=(200, 3 * N))
    return RandomForestCompensator(features="q", n_estimators=3).fit(X, np.sin(X[:, :6]))


def _station(port: int, **keys) -> HardwareStation:
    config = HardwareConfig(lcm_url=_url(port), sensor_timeout_s=10.0,
                            joint_state_timeout_s=10.0, **keys)
    try:
        return HardwareStation(config, _model())
    except ConfigError as e:
        pytest.skip(f"UDP multicast unavailable here ({e})")


def _policies(tids) -> dict:
    return {tid: os.sched_getscheduler(tid) for tid in tids}


def test_new_threads_yield_and_the_callers_keep_their_policy():
    release = threading.Event()
    with NewThreads() as new:
        worker = threading.Thread(target=release.wait)
        worker.start()
    try:
        assert worker.native_id in new.started and os.getpid() not in new.started
        assert new.yield_to_caller() == [worker.native_id]
        assert os.sched_getscheduler(worker.native_id) == BATCH
        assert os.sched_getscheduler(0) == os.SCHED_OTHER
    finally:
        release.set()
        worker.join()


@pytest.mark.parametrize("yield_io_threads", [True, False])
def test_the_lcm_stations_receive_thread_runs_under_sched_batch_unless_told_not(
        yield_io_threads):
    before = set(os.listdir("/proc/self/task"))
    station = _station(PORT, yield_io_threads=yield_io_threads)
    started = {int(t) for t in set(os.listdir("/proc/self/task")) - before}
    assert started, "LCM's udpm receive thread was not started by the station"
    expected = BATCH if yield_io_threads else os.SCHED_OTHER
    assert set(_policies(started).values()) == {expected}
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
    assert station.processed == 0


def test_outputs_on_their_own_url_reach_its_subscribers_and_not_the_input_group():
    station = _station(PORT + 1, output_url=_url(PORT + 2))
    config = station.config
    inputs, outputs = lcm.LCM(config.lcm_url), lcm.LCM(config.output_url)
    seen = {"input group": [], "output url": []}
    channel = config.output_channel("wrench_contact")
    inputs.subscribe(channel, lambda _c, d: seen["input group"].append(d))
    outputs.subscribe(channel, lambda _c, d: seen["output url"].append(decode_wrench(d).t))
    for k in range(5):
        t = 0.001 * (k + 1)
        inputs.publish(config.joint_state_channel,
                       encode_joint_state("iiwa_status", t, np.zeros(N), np.zeros(N)))
        inputs.publish(config.ft_channel, encode_wrench(t, np.zeros(6)))
        while station.processed < k + 1:
            assert station.spin_once(2000) > 0, "the station received nothing"
    while outputs.handle_timeout(500) > 0 and len(seen["output url"]) < 5:
        pass
    inputs.handle_timeout(200)
    np.testing.assert_allclose(seen["output url"], 0.001 * np.arange(1, 6), atol=1e-12)
    assert seen["input group"] == []


def _affinities() -> dict:
    return {tid: frozenset(os.sched_getaffinity(tid)) for tid in thread_ids()}


@pytest.fixture
def restored_affinity():
    """The process's CPUs before the test, put back after it (a test pins every thread)."""
    cpus = usable_cpus()
    if len(cpus) < 2:
        pytest.skip("pinning is seen only with two CPUs or more")
    yield cpus
    pin_process(cpus)


def test_pin_process_puts_every_thread_on_the_cpus(restored_affinity):
    release = threading.Event()
    worker = threading.Thread(target=release.wait)
    worker.start()
    try:
        cpu = max(restored_affinity)
        changed = pin_process([cpu])
        assert {os.getpid(), worker.native_id} <= set(changed)
        assert set(_affinities().values()) == {frozenset({cpu})}
        seen = []
        later = threading.Thread(target=lambda: seen.append(os.sched_getaffinity(0)))
        later.start()
        later.join()
        assert seen == [{cpu}]  # a thread started later inherits its creator's CPUs
    finally:
        release.set()
        worker.join()


def test_an_lcm_station_pins_every_thread_of_the_process_when_told(restored_affinity):
    cpu = min(restored_affinity)
    _station(PORT + 3, cpu_affinity=[cpu])
    assert set(_affinities().values()) == {frozenset({cpu})}
    # Without the key the station leaves the process where it was.
    pin_process(restored_affinity)
    _station(PORT + 4)
    assert set(_affinities().values()) == {frozenset(restored_affinity)}


def test_bad_thread_and_output_keys_name_the_key():
    with pytest.raises(ConfigError, match=r"hardware\.yield_io_threads"):
        HardwareConfig(yield_io_threads="yes").validate()
    with pytest.raises(ConfigError, match=r"hardware\.output_url"):
        HardwareConfig(output_url=7667).validate()
    not_ours = max(usable_cpus() or {0}) + 1
    for bad in ([not_ours], [0, 0], "0", [True], [0.0]):
        with pytest.raises(ConfigError, match=r"hardware\.cpu_affinity: a list of distinct"):
            HardwareConfig(cpu_affinity=bad).validate()
    assert HardwareConfig(cpu_affinity=[]).validate().cpu_affinity == []
