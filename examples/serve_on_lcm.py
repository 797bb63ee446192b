"""Serve the runtime chain on LCM: a robot's joint state and F/T readings in, the compensated
wrench and the contact state out, one update per F/T message.

``ftdrake serve`` does this with a model file and ``--lcm URL``; here the same station runs in
this process on ``memq://`` (LCM's in-process transport; a robot would use
``udpm://239.255.76.67:7667?ttl=0`` or its own URL). The driver's side is played by drake's
message types: ``lcmt_iiwa_status`` (q, v) and ``lcmt_force_torque`` (the reading, N and N·m,
the load the tool applies to the sensor, in S). The readings come from a simulated run of
ftdrake's arm, with a 10 N push on the tool added from t = 1.5 s: the compensated wrench
shows the push, the contact flag rises with it.

Run:  python examples/serve_on_lcm.py
"""

import numpy as np
from drake import lcmt_drake_signal, lcmt_force_torque, lcmt_iiwa_status

import ftdrake

PUSH_AT, PUSH_N = 1.5, np.array([0.0, 0.0, 10.0])  # s; N along S's z


def simulated_log(seed: int, seconds: float):
    config = ftdrake.ScenarioConfig()
    config.trajectory.kind, config.trajectory.duration_s = "fourier", seconds
    config.trajectory.seed = config.sensor.seed = seed
    return ftdrake.simulate(ftdrake.build_station(config), progress=False).log


def fit_model():
    """The tool's rigid-body payload from 4 s of free motion (any ftdrake model file works)."""
    data = simulated_log(seed=0, seconds=4.0)
    return ftdrake.PhysicsPayloadCompensator().fit(ftdrake.joint_state_layout(data),
                                                   ftdrake.wrench_targets(data))


def joint_message(t: float, q, v) -> bytes:
    msg = lcmt_iiwa_status()
    msg.utime, msg.num_joints = round(t * 1e6), len(q)
    msg.joint_position_measured, msg.joint_velocity_estimated = list(q), list(v)
    zeros = [0.0] * len(q)
    msg.joint_position_commanded = msg.joint_position_ipo = zeros
    msg.joint_torque_measured = msg.joint_torque_commanded = msg.joint_torque_external = zeros
    return msg.encode()


def wrench_message(t: float, w) -> bytes:
    msg = lcmt_force_torque()
    msg.timestamp = round(t * 1e6)
    msg.fx, msg.fy, msg.fz, msg.tx, msg.ty, msg.tz = (float(x) for x in w)
    return msg.encode()


def main():
    model = fit_model()
    hardware = ftdrake.HardwareConfig(lcm_url="memq://")  # channels and timeouts: defaults
    station = ftdrake.HardwareStation(hardware, model)
    compensated, contact = [], []
    station.lcm.subscribe(hardware.output_channel("wrench_compensated"),
                          lambda data: compensated.append(lcmt_force_torque.decode(data)))
    station.lcm.subscribe(hardware.output_channel("contact"),
                          lambda data: contact.append(lcmt_drake_signal.decode(data)))

    log = simulated_log(seed=1, seconds=2.0)  # the robot's stream, not trained on
    n = hardware.n_joints
    q = log[[f"q_{i}" for i in range(n)]].to_numpy()
    v = log[[f"qd_est_{i}" for i in range(n)]].to_numpy()
    reading = log[[f"meas_{a}" for a in ftdrake.WRENCH_AXES]].to_numpy()
    times = log["t"].to_numpy()
    for t, qk, vk, wk in zip(times, q, v, reading, strict=True):
        pushed = wk + np.r_[PUSH_N, 0, 0, 0] * (t >= PUSH_AT)
        station.lcm.publish(hardware.joint_state_channel, joint_message(t, qk, vk))
        station.lcm.publish(hardware.ft_channel, wrench_message(t, pushed))
        station.spin_once(0)  # handles what arrived: one update per F/T message
    station.lcm.handle(0)  # the last published messages, to our subscriptions

    force = np.array([[m.fx, m.fy, m.fz] for m in compensated])
    stamp = np.array([m.timestamp * 1e-6 for m in compensated])
    flag = np.array([m.val[0] for m in contact])
    before, after = force[(stamp > 0.5) & (stamp < PUSH_AT)], force[stamp > PUSH_AT + 0.1]
    print(f"F/T messages sent {len(times)}, processed {station.processed}, "
          f"compensated wrenches received {len(compensated)}")
    print(f"compensated force before the push (mean, N): {np.round(before.mean(axis=0), 2)}")
    print(f"compensated force during the push (mean, N): {np.round(after.mean(axis=0), 2)}")
    first = stamp[np.argmax(flag > 0.5)] if (flag > 0.5).any() else None
    print(f"contact first reported at t = {first} s (push from {PUSH_AT} s)")


if __name__ == "__main__":
    main()
