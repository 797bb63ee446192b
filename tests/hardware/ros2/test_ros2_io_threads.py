"""The ROS 2 station's Cyclone DDS threads yield to the chain's thread (hardware/threads.py):
started with the station's participant, they run under SCHED_BATCH unless
``ros2.yield_io_threads`` is false. Each case opens a domain of its own, whose threads the
station starts. With ``ros2.cpu_affinity`` every thread of the process, Cyclone's included,
is kept on those CPUs."""

import os

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from ftdrake import ConfigError, RandomForestCompensator
from ftdrake.hardware.ros2.config import Ros2Config
from ftdrake.hardware.ros2.station import Ros2Station
from ftdrake.hardware.threads import pin_process, thread_ids, usable_cpus

BATCH = getattr(os, "SCHED_BATCH", None)
pytestmark = pytest.mark.skipif(BATCH is None, reason="SCHED_BATCH is Linux's")
NAMES = [f"joint_{k + 1}" for k in range(7)]


def _model():
    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, size=(200, 21))
    return RandomForestCompensator(features="q", n_estimators=3).fit(X, np.sin(X[:, :6]))


@pytest.mark.parametrize(("yield_io_threads", "domain"), [(True, 230), (False, 232)])
def test_the_ros2_stations_dds_threads_run_under_sched_batch_unless_told_not(
        yield_io_threads, domain):  # domains no other test opens: their threads start here
    before = set(os.listdir("/proc/self/task"))
    station = Ros2Station(Ros2Config(joint_names=NAMES, domain_id=domain,
                                     yield_io_threads=yield_io_threads), _model())
    try:
        started = {int(t) for t in set(os.listdir("/proc/self/task")) - before}
        assert started, "no DDS thread was started with the station's participant"
        policies = {os.sched_getscheduler(tid) for tid in started
                    if os.path.exists(f"/proc/self/task/{tid}")}
        assert policies == {BATCH if yield_io_threads else os.SCHED_OTHER}
        assert os.sched_getscheduler(0) == os.SCHED_OTHER
    finally:
        station.close()


def test_the_ros2_station_pins_every_thread_when_told():
    cpus = usable_cpus()
    if len(cpus) < 2:
        pytest.skip("pinning is seen only with two CPUs or more")
    cpu = max(cpus)
    try:
        station = Ros2Station(Ros2Config(joint_names=NAMES, domain_id=228, cpu_affinity=[cpu]),
                              _model())
        try:
            affinities = {frozenset(os.sched_getaffinity(tid)) for tid in thread_ids()
                          if os.path.exists(f"/proc/self/task/{tid}")}
            assert affinities == {frozenset({cpu})}
        finally:
            station.close()
    finally:
        pin_process(cpus)


def test_bad_thread_keys_name_them():
    with pytest.raises(ConfigError, match=r"ros2\.yield_io_threads"):
        Ros2Config(joint_names=NAMES, yield_io_threads=1).validate()
    with pytest.raises(ConfigError, match=r"ros2\.cpu_affinity"):
        Ros2Config(joint_names=NAMES, cpu_affinity=[max(usable_cpus() or {0}) + 1]).validate()
