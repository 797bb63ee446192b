"""docs/guide/your-robot.md runs as written: every command of its ``bash`` blocks, top to
bottom, in one folder, on a robot that is not ftdrake's.

The robot is ``tests/data/seven_joint_arm.urdf`` (the page's ``my_arm.urdf``, sensor frame
``tool``) in the user's own Drake diagram: Drake's InverseDynamicsController, the arm's
reaction at the sensor weld read through ftdrake's noisy sensor, and ``add_recorder``. Its
free-motion runs are written as lcm-logger files (what ``lcm-logger`` records on the wire),
its touch run (a hand pressing on the tool) as a table. The only changes to the page's
commands: ``serve`` listens on ``memq://`` (in-process LCM) for half a second instead of on
the network until Ctrl-C. The logs are seconds long, not minutes.
"""

from __future__ import annotations

import json
import re
import shlex
import shutil

import lcm
import numpy as np
import pandas as pd
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

import ftdrake
from ftdrake.cli.main import main
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import encode_joint_state, encode_wrench
from tests.helpers import DATA, ROOT, Press

PAGE = ROOT / "docs" / "guide" / "your-robot.md"
URDF = DATA / "seven_joint_arm.urdf"
N, PERIOD = 7, 1e-3  # joints; s, the sensor's rate
HOME = np.array([0.0, 0.6, 0.0, -1.2, 0.0, 0.8, 0.0])  # rad
PRESS_N, PRESS = np.array([0.0, 0.0, -10.0]), (2.0, 2.6)  # N in the world; s
LIVE_URL = "udpm://239.255.76.67:7667?ttl=0"


def page_commands() -> list[list[str]]:
    """The ``ftdrake`` commands of the page's ``bash`` blocks, in order, as the shell splits
    them (the ``text`` blocks are alternatives, not run)."""
    blocks = re.findall(r"^```bash\n(.*?)^```", PAGE.read_text(), re.DOTALL | re.MULTILINE)
    commands = [shlex.split(line, comments=True) for block in blocks
                for line in block.splitlines()]
    commands = [c for c in commands if c]
    assert all(c[0] == "ftdrake" for c in commands), commands
    return [c[1:] for c in commands]




def arm(time_step):
    plant = MultibodyPlant(time_step)
    Parser(plant).AddModels(str(URDF))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    for i in range(1, N + 1):  # the URDF declares no transmissions: a motor per joint
        plant.AddJointActuator(f"motor_a{i}", plant.GetJointByName(f"a{i}"))
    plant.Finalize()
    return plant


def motion(seconds, seed):
    """Smooth multi-sine joint motion around HOME (rad), 0.15–0.6 Hz, from rest and back to
    rest (a 1 s ramp at each end: a robot's log does not start with a jolt)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds + 0.01, 0.01)
    ramp = np.clip(np.minimum(t, seconds - t), 0.0, 1.0)
    ramp = ramp * ramp * (3 - 2 * ramp)  # smoothstep
    q = HOME[:, None] + ramp * sum(
        rng.uniform(0.2, 0.4, (N, 1)) * (np.sin(2 * np.pi * f * t + phase) - np.sin(phase))
        for f in (0.15, 0.3, 0.6) for phase in [rng.uniform(0, 6.3, (N, 1))])
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        t, q, np.zeros((N, 1)), np.zeros((N, 1)))


def run_robot(seconds, seed, press=False):
    """The user's robot in their own diagram: its recorded joint state and wrench."""
    builder = DiagramBuilder()
    plant = builder.AddSystem(arm(PERIOD))
    controller = builder.AddSystem(InverseDynamicsController(
        arm(0.0), np.full(N, 400.0), np.zeros(N), np.full(N, 40.0), False))
    q_d = motion(seconds, seed)
    desired = builder.AddSystem(TrajectorySource(q_d, output_derivative_order=1))
    builder.Connect(desired.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(plant.get_state_output_port(), controller.get_input_port_estimated_state())
    builder.Connect(controller.get_output_port_control(), plant.get_actuation_input_port())
    if press:
        hand = builder.AddSystem(Press(plant.GetBodyByName("tool"), PRESS_N, *PRESS))
        builder.Connect(hand.get_output_port(), plant.get_applied_spatial_force_input_port())
    ideal = builder.AddSystem(ftdrake.ForceTorqueSensor(
        plant, plant.GetJointByName("ft_sensor_weld")))
    builder.Connect(plant.get_reaction_forces_output_port(),
                    ideal.get_input_port_reaction_forces())
    sensor = builder.AddSystem(ftdrake.NoisyForceTorqueSensor(ftdrake.SensorConfig(seed=seed)))
    builder.Connect(ideal.get_output_port_wrench(), sensor.get_input_port_wrench_ideal())
    recorder = ftdrake.add_recorder(builder, joint_state=plant.get_state_output_port(),
                                    wrench=sensor.get_output_port_wrench_measured(),
                                    period=PERIOD)
    simulator = Simulator(builder.Build())
    plant.SetPositions(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()),
                       q_d.value(0.0).ravel())
    simulator.AdvanceTo(seconds)
    return recorder.to_frame(simulator.get_context())


def write_lcm_log(frame, path):
    """`frame` as lcm-logger writes the robot's messages: a joint state and a wrench a
    sample, on ftdrake's default channels."""
    config = HardwareConfig()
    q = frame[[f"q_{i}" for i in range(N)]].to_numpy()
    v = frame[[f"qd_{i}" for i in range(N)]].to_numpy()
    w = frame[[f"meas_{a}" for a in ftdrake.WRENCH_AXES]].to_numpy()
    log = lcm.EventLog(str(path), "w", overwrite=True)
    for k, t in enumerate(frame["t"].to_numpy()):
        utime = round(t * 1e6)
        log.write_event(utime, config.joint_state_channel,
                        encode_joint_state("iiwa_status", t, q[k], v[k]))
        log.write_event(utime + 100, config.ft_channel, encode_wrench(t, w[k]))
    log.close()


@pytest.fixture(scope="module")
def robot_folder(tmp_path_factory):
    """The user's folder before step 1: their URDF, two free-motion lcm-logger files and a
    table of a touch."""
    folder = tmp_path_factory.mktemp("my_robot")
    shutil.copy(URDF, folder / "my_arm.urdf")
    write_lcm_log(run_robot(20.0, seed=1), folder / "free.lcmlog")
    write_lcm_log(run_robot(10.0, seed=2), folder / "held_out.lcmlog")
    run_robot(5.0, seed=3, press=True).to_parquet(folder / "touch.parquet", index=False)
    return folder


@pytest.mark.slow
def test_the_your_robot_page_runs_top_to_bottom(robot_folder, monkeypatch, capsys):
    monkeypatch.chdir(robot_folder)
    commands = page_commands()
    assert [c[0] for c in commands] == ["record", "record", "train", "evaluate", "replay",
                                        "replay", "serve"]
    outputs = []
    for argv in commands:
        if argv[0] == "serve":  # in-process LCM, half a second, instead of the network
            assert LIVE_URL in argv
            argv = [("memq://" if a == LIVE_URL else a) for a in argv] + ["--duration", "0.5"]
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == 0, (argv, err[-3000:])
        outputs.append(out)

    assert json.loads(outputs[0])["rows"] == 20000 and json.loads(outputs[1])["rows"] == 10000
    assert (robot_folder / "my_robot.ftd").is_file() and "saved my_robot.ftd" in outputs[2]
    # The tool the URDF gives (1.1 kg) is what the hybrid identified.
    model = ftdrake.load_model(robot_folder / "my_robot.ftd", expect_n_joints=N)
    assert model.identified()["m"]["value"] == pytest.approx(1.1, rel=0.05)
    assert "Fz" in outputs[3]
    calibrated = json.loads(outputs[4].strip().splitlines()[-1])
    assert calibrated["detector"]["file"] == "detector.yaml"
    assert (robot_folder / "detector.yaml").is_file()
    touch = json.loads(outputs[5].strip().splitlines()[-1])
    assert touch["contact_episodes"] == 1, touch  # the press, and nothing else
    replayed = pd.read_parquet(robot_folder / "touch_replay.parquet")
    t, contact = replayed["t"].to_numpy(), replayed["contact"].to_numpy() > 0.5
    first = t[contact][0]
    assert PRESS[0] <= first < PRESS[0] + 0.05 and not contact[t > PRESS[1] + 0.3].any()
    served = json.loads(outputs[6].strip().splitlines()[-1])
    assert served["wall_time_s"] >= 0.5 and "latency_ms" in served


def test_the_page_is_in_the_nav_and_the_home_page_leads_to_it_and_to_ros2():
    nav = (ROOT / "mkdocs.yml").read_text()
    assert "guide/your-robot.md" in nav[nav.index("\nnav:"):]
    home = (ROOT / "docs" / "index.md").read_text()
    where = home[home.index("## Where to go"):]
    assert "](guide/your-robot.md)" in where and "](guide/ros2.md)" in where
    assert "ROS 2" in where
