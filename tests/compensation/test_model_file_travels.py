"""A physics-based model file carries its robot: it loads and predicts from another folder
after the URDF is gone; an older file that named its robot by path is embedded on loading (or
refused with the fix); a tampered robot is refused."""

import hashlib
import os
import shutil
import warnings
import zipfile

import numpy as np
import pytest
import skops.io as sio
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from ftdrake import (
    HybridCompensator,
    ModelFileError,
    PhysicsPayloadCompensator,
    RandomForestCompensator,
    load_model,
    save_model,
)
from ftdrake.compensation.files import persistence
from ftdrake.compensation.files.persistence import read_manifest
from ftdrake.conventions import WRENCH_AXES, WRENCH_UNITS

# A 3-joint arm with a sensor frame at its wrist; its meshes are not shipped with it (a user's
# URDF names files that never travel with a model).
URDF = """<?xml version="1.0"?>
<robot name="little_arm">
  <link name="base"><visual><geometry><mesh filename="package://little_arm/base.stl"/>
  </geometry></visual></link>
  <link name="l1"><inertial><mass value="2"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><mass value="1.5"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
    ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><mesh filename="meshes/l2.obj"/></geometry></collision></link>
  <link name="l3"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="sensor"/>
  <joint name="fix" type="fixed"><parent link="world"/><child link="base"/></joint>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="50" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="50" velocity="2"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.4 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="50" velocity="2"/></joint>
  <joint name="flange" type="fixed"><parent link="l3"/><child link="sensor"/>
    <origin xyz="0.1 0 0" rpy="0.3 -0.2 0.1"/></joint>
</robot>
"""
MASS, COM = 0.9, np.array([0.012, -0.006, 0.065])  # kg; m, in S
BIAS = np.array([0.4, -0.3, 0.2, 0.01, -0.02, 0.015])


def gravity_wrenches(urdf_path, Q):
    """The payload's static reading [m g_S; c × m g_S] + bias from Drake's own kinematics."""
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(urdf_path))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    S = plant.GetFrameByName("sensor")
    rows = []
    for q in Q:
        plant.SetPositions(context, q)
        R_WS = S.CalcPoseInWorld(context).rotation().matrix()
        F = MASS * R_WS.T @ np.array([0.0, 0.0, -9.81])
        rows.append(np.concatenate([F, np.cross(COM, F)]) + BIAS)
    return np.array(rows)


@pytest.fixture
def robot_dir(tmp_path):
    folder = tmp_path / "robot"
    folder.mkdir()
    (folder / "little_arm.urdf").write_text(URDF)
    return folder


def static_poses(seed, n=60):
    """[q, q̇, q̈] rows of the arm at rest (rad, rad/s, rad/s²)."""
    Q = np.random.default_rng(seed).uniform(-2.5, 2.5, (n, 3))
    return Q, np.hstack([Q, np.zeros_like(Q), np.zeros_like(Q)])


def fit_static(urdf_path, seed=0):
    Q, X = static_poses(seed)
    model = PhysicsPayloadCompensator(mode="static", features="q", robot=str(urdf_path),
                                      sensor_frame="sensor")
    return model.fit(X, gravity_wrenches(urdf_path, Q)), X


def save(model, path):
    return save_model(model, path, target_names=WRENCH_AXES, target_units=WRENCH_UNITS)


def test_a_model_file_loads_and_predicts_elsewhere_after_the_urdf_is_gone(robot_dir, tmp_path):
    urdf = robot_dir / "little_arm.urdf"
    model, Q = fit_static(urdf)
    assert model.parameters_[0] == pytest.approx(MASS, rel=1e-9)  # the oracle holds
    before = model.predict(Q)
    path = save(model, tmp_path / "m.ftd")
    manifest = read_manifest(path)
    # The file keeps the robot file's name, not the folder it was in (issue 42 item 15).
    assert manifest["robot"] == {"source": "little_arm.urdf", "portable": True,
                                 "sha256": hashlib.sha256(URDF.encode()).hexdigest()}
    assert model.robot == str(urdf)  # the model in memory keeps its parameter
    shutil.rmtree(robot_dir)  # the URDF moved away, or the file went to another computer
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    cwd = os.getcwd()
    try:
        os.chdir(elsewhere)
        loaded = load_model(path)
    finally:
        os.chdir(cwd)
    np.testing.assert_array_equal(loaded.predict(Q), before)
    assert loaded.robot_portable_
    assert loaded.robot == "little_arm.urdf"
    assert str(robot_dir) not in str(loaded.get_params())


def test_a_file_that_kept_the_robots_full_path_still_loads(robot_dir, tmp_path, monkeypatch):
    """Files written before model files kept only the robot file's name hold its whole path:
    they load and predict as before, after the URDF is gone."""
    model, Q = fit_static(robot_dir / "little_arm.urdf")
    before = model.predict(Q)
    monkeypatch.setattr(persistence, "file_name_only", lambda robot: robot)  # the old writer
    path = save(model, tmp_path / "m.ftd")
    monkeypatch.undo()
    assert read_manifest(path)["robot"]["source"] == str(robot_dir / "little_arm.urdf")
    shutil.rmtree(robot_dir)
    loaded = load_model(path)
    assert loaded.robot == str(robot_dir / "little_arm.urdf")
    np.testing.assert_array_equal(loaded.predict(Q), before)


def test_a_hybrids_physics_part_carries_its_robot(robot_dir, tmp_path):
    urdf = robot_dir / "little_arm.urdf"
    Q, X = static_poses(1, 80)
    Y = gravity_wrenches(urdf, Q)
    physics = PhysicsPayloadCompensator(mode="static", features="q", robot=str(urdf),
                                        sensor_frame="sensor")
    model = HybridCompensator(physics=physics, residual=RandomForestCompensator(
        features="q", n_estimators=3, random_state=0)).fit(X, Y)
    before = model.predict(X)
    path = save(model, tmp_path / "h.ftd")
    shutil.rmtree(robot_dir)
    np.testing.assert_array_equal(load_model(path).predict(X), before)


def old_format_file(model, path):
    """The file an ftdrake before embedded robots wrote: format 2, the robot by path only."""
    del model.robot_model_, model.robot_portable_
    payload = sio.dumps(model, compression=zipfile.ZIP_DEFLATED)
    manifest = {**persistence._manifest(model, WRENCH_AXES, WRENCH_UNITS, "S", None),
                "format_version": 2, "payload_bytes": len(payload),
                "payload_sha256": hashlib.sha256(payload).hexdigest()}
    del manifest["robot"]
    path.write_bytes(persistence._pack(manifest, payload))
    return path


def test_an_older_file_gets_its_robot_embedded_where_the_path_is_there(robot_dir, tmp_path):
    model, Q = fit_static(robot_dir / "little_arm.urdf")
    before = model.predict(Q)
    path = old_format_file(model, tmp_path / "old.ftd")
    with pytest.warns(UserWarning, match="embedded now; save the model again"):
        loaded = load_model(path)
    np.testing.assert_array_equal(loaded.predict(Q), before)
    resaved = save(loaded, tmp_path / "new.ftd")  # the migration: portable from now on
    shutil.rmtree(robot_dir)
    np.testing.assert_array_equal(load_model(resaved).predict(Q), before)


def test_an_older_file_whose_robot_is_gone_is_refused_with_the_fix(robot_dir, tmp_path):
    model, _ = fit_static(robot_dir / "little_arm.urdf")
    path = old_format_file(model, tmp_path / "old.ftd")
    shutil.rmtree(robot_dir)
    with pytest.raises(ModelFileError, match=r"names its robot by path .*no such file.*save it "
                                             r"again"):
        load_model(path)


def test_a_robot_that_does_not_match_the_manifest_is_refused(robot_dir, tmp_path):
    model, _ = fit_static(robot_dir / "little_arm.urdf")
    model.robot_model_ = URDF.replace('xyz="0.4 0 0"', 'xyz="0.5 0 0"')  # a longer link
    payload = sio.dumps(model, compression=zipfile.ZIP_DEFLATED)
    manifest = {**persistence._manifest(model, WRENCH_AXES, WRENCH_UNITS, "S", None),
                "robot": {"source": "x", "portable": True,
                          "sha256": hashlib.sha256(URDF.encode()).hexdigest()},
                "payload_bytes": len(payload),
                "payload_sha256": hashlib.sha256(payload).hexdigest()}
    path = tmp_path / "m.ftd"
    path.write_bytes(persistence._pack(manifest, payload))
    with pytest.raises(ModelFileError, match="embedded robot does not match"):
        load_model(path)


def test_a_robot_that_cannot_be_built_is_refused_when_loading(robot_dir, tmp_path):
    model, _ = fit_static(robot_dir / "little_arm.urdf")
    model.sensor_frame = "no_such_frame"  # as a hand-edited or mismatched file would say
    path = save(model, tmp_path / "m.ftd")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ModelFileError, match="no sensor frame named 'no_such_frame'"):
            load_model(path)
