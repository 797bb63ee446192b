"""Tests for ftdrake.logs: reading tables and bags, derivatives, and every bad-input check."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ftdrake.conventions import wrench_columns
from ftdrake.data.bag import read_bag
from ftdrake.data.logs import LogError, LogWarning, expand_columns, read_table
from ftdrake.signals import savgol_derivative
from tests.helpers import UR3_DATA

UR3 = UR3_DATA
UR3_BAG = UR3 / "ur3_2019-11-27-11-55-35.bag"
UR3_JOINTS = ["Base", "Shoulder", "Elbow", "Wrist 1", "Wrist 2", "Wrist 3"]

RATE_HZ = 125.0
FREQS_HZ = np.array([0.5, 1.0, 2.0])  # one sine per joint
OMEGA = 2 * np.pi * FREQS_HZ


def sine_frame(n_rows: int = 500, rate_hz: float = RATE_HZ) -> pd.DataFrame:
    """Joint j follows sin(ω_j t + 0.3) rad; analytic qd, qdd; a wrench as targets."""
    t = np.arange(n_rows) / rate_hz
    phase = OMEGA * t[:, None] + 0.3
    frame = {"t": t}
    for name, block in [("q", np.sin(phase)), ("qd", OMEGA * np.cos(phase)),
                        ("qdd", -(OMEGA**2) * np.sin(phase))]:
        frame |= {f"{name}_{j}": block[:, j] for j in range(len(OMEGA))}
    frame |= {name: np.cos(t) * k for k, name in enumerate(wrench_columns("meas"))}
    return pd.DataFrame(frame)


def read_quietly(source, **kwargs):
    """read_table, failing on any LogWarning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", LogWarning)
        return read_table(source, **kwargs)


# --- Real UR3 data -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["id1.csv", "id2.csv"])
def test_ur3_csv_with_patterns(name):
    csv = pd.read_csv(UR3 / name)
    dut = read_quietly(UR3 / name, positions="q_*", velocities="qd_*", targets="tau_*")
    assert len(dut) == 750 and dut.n_joints == 6
    assert dut.joint_names == [f"q_{j}" for j in range(6)]
    assert dut.target_names == [f"tau_{j}" for j in range(6)]
    assert dut.derived == ["qdd"]
    assert dut.X().shape == (750, 18)
    np.testing.assert_array_equal(dut.X()[:, :12], csv.iloc[:, 1:13].to_numpy())
    np.testing.assert_array_equal(dut.targets, csv.filter(like="tau_").to_numpy())
    assert np.all(np.diff(dut.t) > 0)
    assert np.median(np.diff(dut.t)) == pytest.approx(1 / 125, rel=1e-3)


def test_ur3_parquet_matches_csv(tmp_path):
    path = tmp_path / "id1.parquet"
    pd.read_csv(UR3 / "id1.csv").to_parquet(path)
    from_csv = read_quietly(UR3 / "id1.csv", positions="q_*", velocities="qd_*",
                            targets="tau_*")
    dut = read_quietly(path, positions=re.compile(r"q_\d+"), velocities=re.compile(r"qd_\d+"),
                       targets=[f"tau_{j}" for j in range(6)])
    assert dut.source == "id1.parquet"
    for name in ("t", "q", "qd", "qdd", "targets"):
        np.testing.assert_array_equal(getattr(dut, name), getattr(from_csv, name))


def test_ur3_bag():
    with pytest.warns(LogWarning) as record:
        dut = read_bag(UR3_BAG, "/arm", gap_factor=1.5)
    assert "2 gap(s)" in str(record[0].message)  # two late messages, see the data README

    with warnings.catch_warnings():
        warnings.simplefilter("error", LogWarning)
        dut = read_bag(UR3_BAG, "/arm")  # default gap_factor 3: no warning
    assert dut.joint_names == UR3_JOINTS
    assert len(dut) == 2179 and dut.n_joints == 6
    assert dut.q.shape == dut.qd.shape == dut.qdd.shape == dut.targets.shape == (2179, 6)
    assert dut.derived == ["qdd"]  # the bag has velocities
    assert dut.target_names == [f"tau_{j}" for j in range(6)]
    assert np.all(np.diff(dut.t) > 0) and dut.t[0] == 0
    assert dut.t[-1] == pytest.approx(17.43, abs=0.01)
    assert dut.t0 == pytest.approx(1574866536.065, abs=1e-3)  # first header stamp, UNIX s
    np.testing.assert_allclose(dut.targets[0], [0, 1.609824, 1.787378, -0.032004, -0.027432,
                                                -0.695844])

    again = read_quietly(dut.to_frame(), velocities="qd_*", accelerations="qdd_*",
                         targets="tau_*")
    np.testing.assert_array_equal(again.X(), dut.X())
    np.testing.assert_array_equal(again.targets, dut.targets)


def test_bag_receive_times_have_more_jitter():
    with pytest.warns(LogWarning, match=r"1 gap\(s\) longer than 3 ×"):
        dut = read_bag(UR3_BAG, "/arm", stamps="receive")
    assert "(receive stamps)" in dut.source and len(dut) == 2179


def test_bag_without_the_topic_lists_its_topics():
    with pytest.raises(LogError, match=r"no topic '/joint_states'.*'/arm \(sensor_msgs"):
        read_bag(UR3_BAG, "/joint_states")
    with pytest.raises(LogError, match="no topic '/wrench'"):
        read_bag(UR3_BAG, "/arm", wrench_topic="/wrench")


# --- A ROS 2 bag with a wrench topic -----------------------------------------------------------


def write_ros2_bag(path, joint_hz=100.0, wrench_hz=500.0, seconds=1.0, header_stamps=True):
    """Joint states (2 joints, no velocities) and a wrench Fx = 1 + 2t linear in time.

    Header stamps equal the receive (write) times, or are zero with `header_stamps` False.
    """
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    types = ts.types
    t_start_ns = 1_700_000_000 * 10**9

    def header(t_s, frame_id=""):
        ns = t_start_ns + round(t_s * 1e9) if header_stamps else 0
        stamp = types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    empty = np.array([], dtype=float)
    with Writer(path, version=9) as writer:
        js = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        ws = writer.add_connection("/ft", "geometry_msgs/msg/WrenchStamped", typestore=ts)
        for t_s in np.arange(0, seconds, 1 / joint_hz):
            msg = types["sensor_msgs/msg/JointState"](
                header=header(t_s), name=["j1", "j0"],
                position=np.array([np.cos(t_s), np.sin(t_s)]), velocity=empty, effort=empty)
            writer.write(js, t_start_ns + round(t_s * 1e9), ts.serialize_cdr(msg, msg.__msgtype__))
        gripper = types["sensor_msgs/msg/JointState"](
            header=header(0.5), name=["finger"], position=np.array([0.01]), velocity=empty,
            effort=empty)
        writer.write(js, t_start_ns + 5 * 10**8, ts.serialize_cdr(gripper, gripper.__msgtype__))
        vec = types["geometry_msgs/msg/Vector3"]
        for t_s in np.arange(0.0013, seconds - 0.1, 1 / wrench_hz):
            wrench = types["geometry_msgs/msg/Wrench"](
                force=vec(x=1 + 2 * t_s, y=0.0, z=-9.81), torque=vec(x=0.0, y=0.0, z=t_s))
            msg = types["geometry_msgs/msg/WrenchStamped"](header=header(t_s, "ft_sensor"),
                                                           wrench=wrench)
            writer.write(ws, t_start_ns + round(t_s * 1e9), ts.serialize_cdr(msg, msg.__msgtype__))


def test_ros2_bag_with_wrench_interpolated_onto_joint_stamps(tmp_path):
    write_ros2_bag(tmp_path / "bag")
    with pytest.warns(LogWarning) as record:
        dut = read_bag(tmp_path / "bag", wrench_topic="/ft", joints=["j0", "j1"])
    messages = " | ".join(str(r.message) for r in record)
    assert "skipped 1 /joint_states message(s)" in messages  # the gripper's
    # Joint states at 0.00 s (before the first wrench) and 0.90..0.99 s (after the last).
    assert "dropped 11 joint state(s) outside" in messages
    assert len(dut) == 89 and dut.joint_names == ["j0", "j1"]
    assert dut.derived == ["qd", "qdd"]
    assert dut.target_names == wrench_columns("meas")
    assert "'ft_sensor'" in dut.source
    t = dut.t  # s since the first joint state, which is also t = 0 of the written signals
    np.testing.assert_allclose(dut.q, np.column_stack([np.sin(t), np.cos(t)]), atol=1e-12)
    np.testing.assert_allclose(dut.targets[:, 0], 1 + 2 * t, atol=1e-9)  # linear: exact
    np.testing.assert_allclose(dut.targets[:, 5], t, atol=1e-9)
    np.testing.assert_allclose(dut.qd[:, 0], np.cos(t), atol=1e-6)

    with pytest.warns(LogWarning):
        nearest = read_bag(tmp_path / "bag", wrench_topic="/ft", align="nearest")
    # The nearest wrench sample is at most half a wrench period (1 ms) away: |ΔFx| ≤ 2 N/s × 1 ms.
    assert np.abs(nearest.targets[:, 0] - (1 + 2 * nearest.t)).max() <= 2e-3 + 1e-9


def test_zero_header_stamps_fall_back_to_receive_time(tmp_path):
    write_ros2_bag(tmp_path / "bag", header_stamps=False)
    with pytest.warns(LogWarning) as record:
        dut = read_bag(tmp_path / "bag", wrench_topic="/ft", joints=["j0", "j1"])
    assert "100 /joint_states message(s) have a zero header stamp" in str(record[1].message)
    assert dut.t0 == pytest.approx(1_700_000_000)
    np.testing.assert_allclose(dut.t, np.arange(1, 90) / 100, atol=1e-9)
    np.testing.assert_allclose(dut.targets[:, 0], 1 + 2 * dut.t, atol=1e-9)


# --- Savitzky–Golay derivatives ----------------------------------------------------------------


@pytest.mark.parametrize("rate_hz", [125.0, 1000.0])
def test_savgol_derivatives_of_sines(rate_hz):
    """0.5–2 Hz sines: error < 0.1 % of the amplitude (ω, ω²) away from the ends, < 0.5 % (qd)
    and < 4 % (qdd) within half a window (0.05 s) of the ends."""
    frame = sine_frame(n_rows=int(4 * rate_hz), rate_hz=rate_hz)
    q = frame.filter(regex=r"^q_").to_numpy()
    dt = 1 / rate_hz
    for deriv, prefix, scale in [(1, "qd", OMEGA), (2, "qdd", OMEGA**2)]:
        dut = savgol_derivative(q, dt, deriv)
        error = np.abs(dut - frame.filter(regex=rf"^{prefix}_").to_numpy()) / scale
        edge = int(0.05 * rate_hz) + 1
        assert error[edge:-edge].max() < 1e-3
        assert error.max() < (5e-3 if deriv == 1 else 4e-2)


def test_missing_derivatives_are_computed_and_recorded():
    frame = sine_frame()
    dut = read_quietly(frame.drop(columns=frame.filter(like="qd").columns), positions="q_*")
    assert dut.derived == ["qd", "qdd"]
    np.testing.assert_allclose(dut.qd, frame.filter(regex=r"^qd_").to_numpy(),
                               atol=5e-3 * OMEGA.max())
    given = read_quietly(frame, positions="q_*", velocities="qd_*", accelerations="qdd_*")
    assert given.derived == []
    np.testing.assert_array_equal(given.qdd, frame.filter(regex=r"^qdd_").to_numpy())


# --- Column selection --------------------------------------------------------------------------


@given(st.permutations([f"q_{j}" for j in range(12)] + ["t", "qd_3", "meas_Fx"]))
def test_patterns_expand_in_natural_order(columns):
    expected = [f"q_{j}" for j in range(12)]
    assert expand_columns("q_*", columns) == expected
    assert expand_columns(re.compile(r"q_\d+"), columns) == expected
    assert expand_columns(["q_10", "q_2"], columns) == ["q_10", "q_2"]  # lists keep their order


def test_pattern_matching_nothing_names_it_and_lists_columns():
    with pytest.raises(LogError, match=r"targets: pattern 'wrench_\*' not found.*'meas_Fx'"):
        read_table(sine_frame(), positions="q_*", targets="wrench_*")
    with pytest.raises(LogError, match=r"column\(s\) \['q_7'\] not found; available"):
        read_table(sine_frame(), positions=["q_0", "q_7"])
    with pytest.raises(LogError, match=r"no time column 'time'; the table has \['t'\]: "
                                        r"choose it with time='t'"):
        read_table(sine_frame(), time="time")


def test_velocity_pattern_catching_extra_columns_is_an_error():
    frame = sine_frame()
    frame["qd_est_0"] = frame["qd_0"]  # simulated logs have qd_est_* next to qd_*
    frame["qd_est_1"], frame["qd_est_2"] = frame["qd_1"], frame["qd_2"]
    with pytest.raises(LogError, match=(
            r"^DataFrame: velocities='qd_\*' matched 6 columns \(qd_0..qd_2, qd_est_0..qd_est_2\) "
            r"for 3 positions \(q_0..q_2\); one velocity column per position is needed: "
            r"re:qd_\\d\+ matches 3 \(qd_0..qd_2\): velocities='re:qd_\\\\d\+'$")):
        read_table(frame, velocities="qd_*")
    log = read_table(frame, velocities=r"re:qd_\d+")  # the pattern the message suggests
    np.testing.assert_array_equal(log.qd[:, 2], frame["qd_2"])


def test_non_numeric_column():
    frame = sine_frame()
    frame["q_1"] = frame["q_1"].astype(object)
    frame.loc[12, "q_1"] = "n/a?"
    with pytest.raises(LogError, match=r"'q_1' is not numeric .*1 non-numeric values; row 12"):
        read_table(frame)


# --- Bad rows and units ------------------------------------------------------------------------


def test_nan_and_inf_rows_are_dropped_and_counted():
    frame = sine_frame()
    frame.loc[[10, 20, 20], ["q_0", "q_1", "q_2"]] = np.nan
    frame.loc[30, "meas_Tz"] = np.inf
    frame.loc[40, "t"] = np.nan
    with pytest.warns(LogWarning, match=r"dropped 4 of 500 rows with NaN/inf "
                                        r"\(t: 1, q: 2, targets: 1\)"):
        dut = read_table(frame)
    assert len(dut) == 496 and np.isfinite(dut.X()).all()


def test_unsorted_timestamps_raise_for_tables():
    frame = sine_frame()
    frame.iloc[[100, 101]] = frame.iloc[[101, 100]].to_numpy()
    frame.iloc[[300, 301]] = frame.iloc[[301, 300]].to_numpy()
    with pytest.raises(LogError, match=r"backwards at 2 row\(s\) \(first from 0.808 to 0.8 s"):
        read_table(frame)
    dut = read_quietly(frame.sort_values("t"))  # the way out the message suggests
    # Sorted, the swapped rows are back in place: the log is the unswapped table's rows.
    original = sine_frame()
    np.testing.assert_array_equal(dut.t, original["t"].to_numpy())
    np.testing.assert_array_equal(dut.q, original.filter(regex=r"^q_").to_numpy())
    np.testing.assert_array_equal(dut.targets, original[wrench_columns("meas")].to_numpy())


def test_duplicate_timestamps_are_dropped_and_counted():
    frame = sine_frame()
    frame = pd.concat([frame, frame.iloc[[5, 50, 60]]]).sort_values("t", kind="stable")
    with pytest.warns(LogWarning, match=r"dropped 3 row\(s\) repeating an earlier timestamp"):
        dut = read_table(frame)
    assert len(dut) == 500


def test_gaps_are_counted_and_derivatives_stay_accurate():
    frame = sine_frame().drop(index=list(range(100, 105)) + list(range(300, 310)))
    with pytest.warns(LogWarning, match=r"2 gap\(s\) longer than 3 × .* longest 0.088 s"):
        dut = read_table(frame)
    assert len(dut) == 485
    true_qd = frame.filter(regex=r"^qd_").to_numpy()
    np.testing.assert_allclose(dut.qd, true_qd, atol=5e-3 * OMEGA.max())


def test_degrees_are_detected_and_converted():
    frame = sine_frame()
    degrees = frame.copy()
    for prefix in ("q", "qd", "qdd"):
        cols = degrees.filter(regex=rf"^{prefix}_").columns
        degrees[cols] = np.rad2deg(degrees[cols]) + (90.0 if prefix == "q" else 0.0)
    with pytest.raises(LogError, match=r"look like degrees: 3 of 3 joints exceed 2π"):
        read_table(degrees, velocities="qd_*")
    dut = read_quietly(degrees, velocities="qd_*", position_unit="deg")
    np.testing.assert_allclose(dut.q, frame.filter(regex=r"^q_").to_numpy() + np.pi / 2)
    np.testing.assert_allclose(dut.qd, frame.filter(regex=r"^qd_").to_numpy())


@pytest.mark.parametrize("factor, expected", [(180 / np.pi, "57.3 ×"), (0.0, "0 ×")])
def test_velocities_disagreeing_with_positions(factor, expected):
    frame = sine_frame()
    cols = frame.filter(regex=r"^qd_").columns
    frame[cols] *= factor  # deg/s next to rad; or a driver that publishes zeros
    with pytest.raises(LogError, match=f"given qd is {expected}"):
        read_table(frame, velocities="qd_*")
    # Turned off, the check lets the user's velocities through as given (not converted, not
    # replaced by the positions' derivative).
    dut = read_quietly(frame, velocities="qd_*", check_units=False)
    assert dut.derived == ["qdd"]
    np.testing.assert_array_equal(dut.qd, frame[cols].to_numpy())


def test_a_log_at_rest_with_zero_velocities_is_fine():
    rng = np.random.default_rng(0)
    frame = sine_frame()
    q_cols, qd_cols = frame.filter(regex=r"^q_").columns, frame.filter(regex=r"^qd_").columns
    frame[q_cols] = 0.3 + rng.normal(0, 1e-5, (len(frame), len(q_cols)))  # encoder noise
    frame[qd_cols] = 0.0
    dut = read_quietly(frame, velocities="qd_*")  # no unit error: the derivative is noise too
    assert len(dut) == 500 and dut.derived == ["qdd"]
    np.testing.assert_array_equal(dut.q, frame[q_cols].to_numpy())
    np.testing.assert_array_equal(dut.qd, np.zeros((500, 3)))


def test_too_few_rows():
    with pytest.raises(LogError, match="only 9 usable rows"):
        read_table(sine_frame(n_rows=9))
