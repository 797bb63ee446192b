"""Train a compensator from a ROS bag and check it on another bag.

A robot's log is often a ROS bag: ``sensor_msgs/JointState`` (positions, velocities) and
``geometry_msgs/WrenchStamped`` (the F/T sensor) on their own topics and clocks. ftdrake
reads it with ``rosbags`` (ROS 1 ``.bag`` files or ROS 2 bag folders), puts the wrench on the
joint-state stamps and computes the missing accelerations. Here the two bags are written
from simulated runs of ftdrake's arm (your robot's bags replace them) and the model is the
tool's rigid-body payload on that arm (``PhysicsPayloadCompensator``; for your robot pass
``robot="arm.urdf", sensor_frame="ft_link"``).

Run:  python examples/train_from_a_bag.py          (the command: ftdrake train --data BAG ...)
"""

from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

import ftdrake

JOINTS = "/joint_states"
WRENCH = "/ft_sensor/wrench"


def simulated_log(seed: int, seconds: float = 6.0):
    """A free-motion run of ftdrake's arm (what your robot would have recorded)."""
    config = ftdrake.ScenarioConfig()
    config.trajectory.kind, config.trajectory.duration_s = "fourier", seconds
    config.trajectory.seed = config.sensor.seed = seed
    return ftdrake.simulate(ftdrake.build_station(config), progress=False).log


def write_bag(log, path: Path, joint_every: int = 4) -> Path:
    """A ROS 2 bag: joint states at 250 Hz, the wrench at the sensor's 1 kHz."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    msg = store.types
    n = sum(c.startswith("q_") for c in log.columns)
    names = [f"joint_{i}" for i in range(n)]
    t0 = 1_700_000_000 * 10**9  # ns

    def header(t: float):
        ns = t0 + round(t * 1e9)
        stamp = msg["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        return ns, msg["std_msgs/msg/Header"](stamp=stamp, frame_id="ft_sensor")

    q = log[[f"q_{i}" for i in range(n)]].to_numpy()
    v = log[[f"qd_est_{i}" for i in range(n)]].to_numpy()  # what a driver estimates
    w = log[[f"meas_{a}" for a in ftdrake.WRENCH_AXES]].to_numpy()
    vector = msg["geometry_msgs/msg/Vector3"]
    with Writer(path, version=9) as bag:
        joints = bag.add_connection(JOINTS, "sensor_msgs/msg/JointState", typestore=store)
        wrench = bag.add_connection(WRENCH, "geometry_msgs/msg/WrenchStamped", typestore=store)
        for k, t in enumerate(log["t"].to_numpy()):
            ns, head = header(t)
            if k % joint_every == 0:
                state = msg["sensor_msgs/msg/JointState"](
                    header=head, name=names, position=np.ascontiguousarray(q[k]),
                    velocity=np.ascontiguousarray(v[k]),
                    effort=np.zeros(0))
                bag.write(joints, ns, store.serialize_cdr(state, state.__msgtype__))
            reading = msg["geometry_msgs/msg/WrenchStamped"](header=head, wrench=msg[
                "geometry_msgs/msg/Wrench"](force=vector(x=w[k, 0], y=w[k, 1], z=w[k, 2]),
                                            torque=vector(x=w[k, 3], y=w[k, 4], z=w[k, 5])))
            bag.write(wrench, ns, store.serialize_cdr(reading, reading.__msgtype__))
    return path


def main():
    out = Path("out")
    out.mkdir(exist_ok=True)
    train_bag = write_bag(simulated_log(seed=0), out / "train_bag")
    test_bag = write_bag(simulated_log(seed=1), out / "test_bag")

    options = ftdrake.ReadOptions(wrench_topic=WRENCH)  # targets: the wrench, meas_Fx..meas_Tz
    train = ftdrake.load_training_data(train_bag, options, report=print)
    print(f"{train_bag}: {len(train.X)} rows, joints {train.joint_names}, computed {train.derived}")
    model = ftdrake.PhysicsPayloadCompensator().fit(train.X, train.Y)  # ftdrake's arm
    print(f"identified tool mass: {model.parameters_[0]:.3f} kg "
          "(the simulated tool is 1.5 kg; the cable's hanging weight adds about 0.12 kg)")
    path = ftdrake.save_model(model, out / "bag_model.ftd", target_names=ftdrake.WRENCH_AXES,
                              target_units=ftdrake.WRENCH_UNITS, sensor_frame="S")

    test = ftdrake.load_training_data(test_bag, options)
    noise = np.asarray(ftdrake.SensorConfig().spec().noise_std)
    rms = np.sqrt(np.mean((ftdrake.load_model(path).predict(test.X) - test.Y) ** 2, axis=0))
    print(f"held-out bag: residual RMS / noise σ per axis: {np.round(rms / noise, 2)}")
    print(f"saved {path}")


if __name__ == "__main__":
    main()
