"""The chain computes gravity at the sensor on the model's own robot, on every station.

A physics model trained on a 7-joint arm that is not ftdrake's (``tests/data/
seven_joint_arm.urdf``) carries that arm in its file. With payload tracking, the live LCM
station and ``replay`` must compute g_S from the joint state on that arm, never on
ftdrake's simulated arm (which has 7 joints too, so nothing else would complain). The
reference is Drake's own plant of the URDF, built here without ftdrake.
"""


import numpy as np
import pandas as pd
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

import ftdrake
from ftdrake import conventions as col
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.messages import encode_joint_state, encode_wrench
from tests.helpers import DATA

URDF = DATA / "seven_joint_arm.urdf"
N = 7
G_W = np.array([0.0, 0.0, -9.81])
TOOL_MASS, TOOL_COM = 1.1, np.array([0.01, -0.015, 0.08])  # the URDF's tool, in S
POSES = np.array([[0.3, 0.5, -0.4, -1.2, 0.6, 0.9, 0.2],
                  [-0.8, 1.1, 0.7, -0.5, -1.0, 0.4, -0.6],
                  [1.4, -0.6, 0.2, -1.6, 1.2, -0.8, 1.0],
                  [0.0, 0.9, -1.1, -0.9, -0.4, 1.3, 0.5]])


def drake_g_S(q: np.ndarray) -> np.ndarray:
    """Gravity in S at `q`, from Drake's plant of the URDF alone."""
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(file_name=str(URDF))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    R_WS = plant.GetFrameByName("tool").CalcPoseInWorld(context).rotation().matrix()
    return R_WS.T @ G_W


def weight_wrench(g_S: np.ndarray, mass: float, com: np.ndarray) -> np.ndarray:
    """A point mass's gravity wrench at So in S: [m·g_S, c × m·g_S]."""
    return np.r_[mass * g_S, np.cross(com, mass * g_S)]


@pytest.fixture(scope="module")
def model():
    """The tool's payload model identified on the user's arm from static poses."""
    rng = np.random.default_rng(4)
    q = rng.uniform(-2.0, 2.0, (60, N))
    Y = np.array([weight_wrench(drake_g_S(row), TOOL_MASS, TOOL_COM) for row in q])
    X = np.hstack([q, np.zeros((60, 2 * N))])
    return ftdrake.PhysicsPayloadCompensator(
        features="q", mode="static", robot=str(URDF), sensor_frame="tool",
        base_frame="base").fit(X, Y)


def tracking_chain() -> ftdrake.ChainConfig:
    config = ftdrake.ChainConfig()
    config.bias_tracker.track_payload = True
    config.bias_tracker.track_payload_motion = False
    return config


def test_the_live_station_computes_gravity_on_the_models_robot(model):
    hardware = HardwareConfig(lcm_url="memq://", sensor_timeout_s=10.0,
                              joint_state_timeout_s=10.0)
    station = HardwareStation(hardware, model, tracking_chain(), "memq://")
    assert station.chain.robot.model == model.robot_description().model
    gravity = station.chain.gravity
    k = 0
    for q in POSES:
        for _ in range(200):  # held still: the q̈ estimate settles at 0, so a_So = 0
            k += 1
            t = k * station.period
            station.lcm.publish(hardware.joint_state_channel,
                                encode_joint_state("iiwa_status", t, q, np.zeros(N)))
            station.lcm.publish(hardware.ft_channel, encode_wrench(t, model.predict(
                np.r_[q, np.zeros(2 * N)][None])[0]))
            station.spin_once(0)
            station.lcm.handle(0)
        g_S = gravity.get_output_port_gravity_S().Eval(
            gravity.GetMyContextFromRoot(station.chain_context()))
        np.testing.assert_allclose(g_S, drake_g_S(q), rtol=0, atol=1e-9)


def test_replay_identifies_a_grasp_with_the_models_robot(model):
    """A 0.4 kg payload grasped (signalled) while the arm holds four poses: the tracker's
    Δm and Δ(m·c) come out right only when g_S is computed on the user's arm."""
    mass, com = 0.4, np.array([0.02, 0.0, 0.11])
    rows, period, per_pose = [], 1e-3, 1500
    for i, q in enumerate(POSES):
        tool = weight_wrench(drake_g_S(q), TOOL_MASS, TOOL_COM)
        payload = weight_wrench(drake_g_S(q), mass, com)
        for j in range(per_pose):
            k = i * per_pose + j
            grasped = k >= 500
            rows.append([k * period, *q, *np.zeros(N), *(tool + payload * grasped),
                         float(k == 500)])
    columns = [col.TIME, *col.joint_columns(col.Q, N), *col.joint_columns(col.QD, N),
               *col.wrench_columns(col.MEASURED), "payload_changed"]
    log = pd.DataFrame(rows, columns=columns)
    config = tracking_chain()
    config.bias_tracker.payload_settle_s = 4.0
    out = ftdrake.replay(model, log, config)
    payload = out[list(col.PAYLOAD)].to_numpy()[-1]
    assert payload[0] == pytest.approx(mass, rel=0.01)
    np.testing.assert_allclose(payload[1:], mass * com, rtol=0, atol=2e-3)


def test_a_model_without_a_robot_must_be_given_one():
    """A forest knows no robot: payload tracking then asks for chain.robot (--robot)."""
    forest = ftdrake.RandomForestCompensator(features="q", n_estimators=2).fit(
        np.random.default_rng(0).uniform(-1, 1, (40, 3 * N)), np.zeros((40, 6)))
    with pytest.raises(ftdrake.ConfigError, match=r"chain\.robot.*--robot"):
        ftdrake.CompensationChain(forest, tracking_chain())
    given = tracking_chain()
    given.robot = ftdrake.RobotConfig(file=str(URDF), sensor_frame="tool", base_frame="base")
    chain = ftdrake.CompensationChain(forest, given)
    assert chain.robot.model == str(URDF) and chain.robot.sensor_frame == "tool"


def test_replay_command_takes_the_robot_and_a_chain_config_file(tmp_path, capsys):
    """``replay --robot FILE --sensor-frame NAME`` gives a forest's payload tracking its
    kinematics; ``--config`` reads a chain config file; a scenario file still loads, with a
    warning naming the chain layout; a frame without its robot names the flag."""
    from ftdrake.cli.main import main

    rng = np.random.default_rng(1)
    q = rng.uniform(-1, 1, (300, N))
    forest = ftdrake.RandomForestCompensator(features="q", n_estimators=2).fit(
        np.hstack([q, np.zeros((300, 2 * N))]), np.zeros((300, 6)))
    ftdrake.save_model(forest, tmp_path / "forest.ftd")
    frame = pd.DataFrame(np.hstack([np.arange(300)[:, None] * 1e-3, q, np.zeros((300, N)),
                                    np.zeros((300, 6))]),
                         columns=[col.TIME, *col.joint_columns(col.Q, N),
                                  *col.joint_columns(col.QD, N),
                                  *col.wrench_columns(col.MEASURED)])
    frame.to_csv(tmp_path / "log.csv", index=False)
    (tmp_path / "chain.yaml").write_text("bias_tracker: {track_payload: true}\n")
    base = ["replay", "--model", tmp_path / "forest.ftd", "--log", tmp_path / "log.csv",
            "--out", tmp_path / "out.csv", "--config", tmp_path / "chain.yaml"]
    assert main([str(a) for a in base]) == 2  # a forest: no robot to compute gravity on
    assert "--robot FILE --sensor-frame NAME" in capsys.readouterr().err
    assert main([str(a) for a in [*base, "--sensor-frame", "tool"]]) == 2
    assert "--sensor-frame/--base-frame name frames of --robot" in capsys.readouterr().err
    robot = ["--robot", URDF, "--sensor-frame", "tool", "--base-frame", "base"]
    assert main([str(a) for a in [*base, *robot]]) == 0
    assert "payload_dm" in pd.read_csv(tmp_path / "out.csv")
    (tmp_path / "scenario.yaml").write_text(
        "time_step: 0.001\nbias_tracker: {track_payload: true}\n")
    old = [*base[:-1], tmp_path / "scenario.yaml", *robot]
    capsys.readouterr()
    assert main([str(a) for a in old]) == 0
    err = capsys.readouterr().err
    assert "a scenario file where a chain config is expected" in err
    assert "now live under 'chain:'" in err
