"""ROS 2 recordings for train/evaluate: ``ftdrake record --ros2`` writes a simulated robot's
topics in the ``collect`` layout, row for row the simulation's own log; and a ROS 2 bag
written with rosbags (sqlite3 and MCAP storage) from a simulated run trains a model that
``evaluate`` scores as it scores one trained on the equivalent Parquet table."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("cyclonedds")
from rosbags.rosbag2 import StoragePlugin, Writer

from ftdrake.cli.main import main as train_cli
from ftdrake.config import ScenarioConfig, save_config
from ftdrake.conventions import MEASURED, QD, Q, joint_columns, wrench_columns
from ftdrake.hardware.ros2.config import Ros2Config
from ftdrake.hardware.ros2.messages import typestore
from ftdrake.sim.ros2_publisher import arm_joint_names, simulate_on_ros2
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station

DOMAIN = 100 + (os.getpid() + 37) % 100


def free_scenario(duration, seed=0):
    scenario = ScenarioConfig()
    scenario.trajectory.kind = "fourier"
    scenario.trajectory.duration_s = duration
    scenario.seed = seed
    return scenario.validate()


def test_record_writes_the_collect_layout(tmp_path):
    scenario = free_scenario(1.0)
    station = build_station(scenario)
    names = arm_joint_names(station)
    config = Ros2Config(joint_names=names, domain_id=DOMAIN).validate()
    save_config(config, tmp_path / "ros2.yaml")
    err_path = tmp_path / "record.err"
    with open(err_path, "w") as err:
        record = subprocess.Popen(
            [sys.executable, "-m", "ftdrake", "record", "--ros2", "--ros2-config",
             tmp_path / "ros2.yaml", "--out", tmp_path / "rec.parquet"],
            stdout=subprocess.PIPE, stderr=err, text=True)
    try:
        end = time.monotonic() + 60
        while "ftdrake record:" not in err_path.read_text():
            assert record.poll() is None and time.monotonic() < end, err_path.read_text()
            time.sleep(0.05)
        result = simulate_on_ros2(station, config, realtime_rate=1.0, progress=False,
                                  wait_for_subscriber_s=10.0)
        time.sleep(0.5)
        record.send_signal(signal.SIGINT)
        out, _ = record.communicate(timeout=60)
    finally:
        if record.poll() is None:
            record.kill()
    assert record.returncode == 0, err_path.read_text()
    report = json.loads(out.strip().splitlines()[-1])
    K = result.timing["published"]["ft"]
    assert report == {"out": str(tmp_path / "rec.parquet"), "ft": K, "joint": K + 1,
                      "rows": K, "unmatched_ft": 0, "unused_joint": 1}
    table = pd.read_parquet(tmp_path / "rec.parquet")
    n = len(names)
    columns = ["t", *joint_columns(Q, n), *joint_columns(QD, n), *wrench_columns(MEASURED)]
    assert list(table.columns) == columns
    # Row k: the F/T message stamped t_k with the joint state stamped t_k, i.e. the log's row
    # at t_k (the log starts at t_1: its row at t = 0 is dropped).
    np.testing.assert_array_equal(table[columns[1:]].to_numpy()[1:],
                                  result.log[columns[1:]].to_numpy()[:K - 1])
    np.testing.assert_allclose(table["t"].to_numpy()[1:], result.log["t"].to_numpy()[:K - 1],
                               rtol=0, atol=1e-12)  # stamps: integer ns


def test_the_recorder_takes_the_configured_joints_by_name_and_ignores_others():
    """A robot's /joint_states with a gripper's joint among the arm's: the arm's are kept in
    joint_names' order; a message missing one, or naming one twice, is not used."""
    from ftdrake.hardware.ros2.messages import header, ros2_type
    from ftdrake.hardware.ros2.recording import Ros2Recorder

    names = [f"arm_joint_{k}" for k in range(1, 8)]
    recorder = Ros2Recorder(Ros2Config(joint_names=names, domain_id=DOMAIN).validate())
    joint_state = ros2_type("sensor_msgs/msg/JointState")
    try:
        for sent in (["finger_joint", *reversed(names)], names[:6], [*names, names[0]]):
            q = [float(names.index(n)) if n in names else 9.0 for n in sent]
            recorder._on_joint(joint_state(header=header(0.001), name=sent, position=q,
                                           velocity=[0.5 * x for x in q], effort=[]), 0.0)
    finally:
        recorder.close()
    (row,) = recorder.joints
    np.testing.assert_array_equal(row, [0.001, *range(7), *(0.5 * np.arange(7))])
    assert recorder.rejected == {"joint_names": 2}


def write_bag(log, path, storage, names):
    """The log as a ROS 2 bag: JointState on /joint_states, WrenchStamped on /ft_sensor/wrench,
    both stamped with the row's time, serialised by rosbags."""
    store = typestore()
    T, H = store.types["builtin_interfaces/msg/Time"], store.types["std_msgs/msg/Header"]
    JS = store.types["sensor_msgs/msg/JointState"]
    WS = store.types["geometry_msgs/msg/WrenchStamped"]
    V, W = store.types["geometry_msgs/msg/Vector3"], store.types["geometry_msgs/msg/Wrench"]
    n = len(names)
    q = np.ascontiguousarray(log[joint_columns(Q, n)].to_numpy())
    qd = np.ascontiguousarray(log[joint_columns(QD, n)].to_numpy())
    w = log[wrench_columns(MEASURED)].to_numpy()
    with Writer(path, version=9, storage_plugin=storage) as bag:
        joints = bag.add_connection("/joint_states", JS.__msgtype__, typestore=store)
        wrench = bag.add_connection("/ft_sensor/wrench", WS.__msgtype__, typestore=store)
        for k, t in enumerate(log["t"].to_numpy()):
            ns = round(t * 1e9)
            stamp = T(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
            bag.write(joints, ns, store.serialize_cdr(JS(
                header=H(stamp=stamp, frame_id=""), name=list(names), position=q[k],
                velocity=qd[k], effort=np.zeros(0)), JS.__msgtype__))
            bag.write(wrench, ns, store.serialize_cdr(WS(
                header=H(stamp=stamp, frame_id="ft_sensor"),
                wrench=W(force=V(*w[k, :3]), torque=V(*w[k, 3:]))), WS.__msgtype__))


def run(*argv):
    assert train_cli([str(a) for a in argv]) == 0


def scores(path):
    result = json.loads(path.read_text())
    return {name: (m["variance_score"], m["mse"]) for name, m in result["metrics"]["all"].items()}


def test_bags_train_like_parquet(tmp_path):
    station_train = build_station(free_scenario(2.0, seed=1))
    names = arm_joint_names(station_train)
    n = len(names)
    columns = ["t", *joint_columns(Q, n), *joint_columns(QD, n), *wrench_columns(MEASURED)]
    logs = {"train": simulate(station_train, progress=False).log[columns],
            "test": simulate(build_station(free_scenario(1.0, seed=2)), progress=False)
            .log[columns]}
    for kind, log in logs.items():
        log = log.assign(t=log["t"] - log["t"].iloc[0])  # a bag's time axis starts at 0
        log.to_parquet(tmp_path / f"{kind}.parquet", index=False)
        for storage in (StoragePlugin.SQLITE3, StoragePlugin.MCAP):
            write_bag(log, tmp_path / f"{kind}_{storage.name.lower()}", storage, names)
    assert (tmp_path / "train_mcap").is_dir() and any((tmp_path / "train_mcap").glob("*.mcap"))

    fit = ["--model", "rf", "--preset", "none"]
    run("train", "--data", tmp_path / "train.parquet", "--out", tmp_path / "table.ftd",
        "--velocities", "qd_*", *fit)
    run("evaluate", "--model", tmp_path / "table.ftd", "--data", tmp_path / "test.parquet",
        "--json", tmp_path / "table.json")
    reference = scores(tmp_path / "table.json")
    assert set(reference) == set(wrench_columns(MEASURED))
    assert sum(v > 0.9 for v, _ in reference.values()) >= 2  # a model that learned something
    for storage in ("sqlite3", "mcap"):
        model = tmp_path / f"{storage}.ftd"
        run("train", "--data", tmp_path / f"train_{storage}", "--out", model,
            "--wrench-topic", "/ft_sensor/wrench", "--targets", "wrench", *fit)
        run("evaluate", "--model", model, "--data", tmp_path / f"test_{storage}",
            "--json", tmp_path / f"{storage}.json")
        got = scores(tmp_path / f"{storage}.json")
        assert set(got) == set(reference)
        for name, (variance, mse) in reference.items():
            assert got[name][0] == pytest.approx(variance, rel=1e-9, abs=1e-12), (storage, name)
            assert got[name][1] == pytest.approx(mse, rel=1e-9, abs=1e-12), (storage, name)
