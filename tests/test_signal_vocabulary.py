"""One name per signal: the table of the chain's outputs (conventions.CHAIN_OUTPUTS) against
the chain's ports, what the live stations publish and record, the docs, and logs written by
the earlier release (tests/data/*_eb9851c.*: a simulated contact log saved with
``save_dataset`` and a ``replay`` result written as ``ftdrake replay --out x.csv`` writes it,
both by the code of commit eb9851c)."""

import importlib.util

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

import ftdrake
from ftdrake import RandomForestCompensator, ScenarioConfig
from ftdrake import conventions as col
from ftdrake.data.logs import read_frame, write_log
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.messages import (
    CONTACT_COORDS,
    decode_contact_state,
    decode_payload,
    decode_wrench,
    encode_joint_state,
    encode_wrench,
)
from ftdrake.hardware.ros2.config import OUTPUTS as ROS2_OUTPUTS
from ftdrake.runtime.chain import CompensationChain
from tests.helpers import DATA, ROOT

N = 7


def small_forest(seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1, 1, size=(200, 3 * N))
    return RandomForestCompensator(features="q", n_estimators=3, random_state=seed).fit(
        X, np.sin(X[:, :6]) * 3.0)


def tracking_scenario():
    """Every output port: the tracker with the payload and its change monitor (a forest
    carries no robot: joint-state gravity on the simulated arm)."""
    config = ftdrake.ChainConfig()
    config.bias_tracker.track_payload = True
    config.bias_tracker.payload_change.enabled = True
    config.robot.file = "ftdrake"
    return config.validate()


def test_every_output_port_of_the_chain_has_one_row_and_its_names_are_unique():
    chain = CompensationChain(small_forest(), tracking_scenario(), period=0.001,
                              n_joints=N, gravity="input")
    ports = {chain.get_output_port(i).get_name(): chain.get_output_port(i).size()
             for i in range(chain.num_output_ports())}
    assert ports == {o.port: o.size for o in col.CHAIN_OUTPUTS}
    for o in col.CHAIN_OUTPUTS:
        assert len(o.columns) == o.size
        assert all(c == o.port or c.startswith(o.port + "_") for c in o.columns), o
    columns = [c for o in col.CHAIN_OUTPUTS for c in o.columns]
    truth = [col.CONTACT_TRUE, *col.wrench_columns(col.INTERNAL_TRUE),
             *col.wrench_columns(col.EXTERNAL_TRUE)]
    assert len(set(columns)) == len(columns) and not set(columns) & set(truth)
    # Every old name goes to a name of today's (an estimate's or the truth's).
    assert set(col.LEGACY_COLUMNS.values()) <= set(columns) | set(truth)


def test_lcm_and_ros2_publish_the_same_outputs_under_the_ports_names():
    diagnostics = {o.port for o in col.CHAIN_OUTPUTS
                   if o.ros2 and o.ros2 == f"/diagnostics.{o.port}"}
    assert set(ROS2_OUTPUTS) | diagnostics == set(col.PUBLISHED)
    assert {"wrench_contact", "wrench_compensated", "contact", "fault"} <= set(col.PUBLISHED)
    hardware = HardwareConfig()
    on_lcm = {port for ports in hardware.output_channels().values()
              for port in ports.split(", ")}
    assert on_lcm == set(col.PUBLISHED)
    assert hardware.output_channel("wrench_contact") == "FT_WRENCH_CONTACT"
    assert set(CONTACT_COORDS) == {o.port for o in col.CHAIN_OUTPUTS
                                   if o.lcm_channel == "CONTACT_STATE"}


def test_an_earlier_hardware_file_keeps_its_channels_for_a_release():
    with pytest.warns(FutureWarning, match="external_wrench_channel is deprecated"):
        old = HardwareConfig(external_wrench_channel="FT_EXTERNAL_WRENCH").validate()
    assert old.output_channel("wrench_compensated") == "FT_EXTERNAL_WRENCH"
    assert old.output_channel("wrench_contact") == "FT_WRENCH_CONTACT"
    with pytest.raises(ftdrake.ConfigError,
                       match=r"output_prefix \(bias\): channel 'FT_BIAS' is also hardware.ft_ch"):
        HardwareConfig(ft_channel="FT_BIAS").validate()


@pytest.fixture(scope="module")
def live_run():
    """A station on memq:// with the tracker following the payload, fed 300 messages while
    recording: (model, scenario, station, the recording, {channel: decoded messages})."""
    model, scenario = small_forest(1), tracking_scenario()
    hardware = HardwareConfig(lcm_url="memq://", sensor_timeout_s=10.0,
                              joint_state_timeout_s=10.0)
    station = HardwareStation(hardware, model, scenario, "memq://")
    recorder = station.start_recording()
    got = {port: [] for port in col.PUBLISHED}
    decoders = {"wrench_contact": decode_wrench, "wrench_compensated": decode_wrench,
                "bias": decode_wrench, "payload": decode_payload,
                "contact": decode_contact_state}
    for port, decode in decoders.items():
        station.lcm.subscribe(hardware.output_channel(port),
                              lambda d, p=port, f=decode: got[p].append(f(d)))
    rng = np.random.default_rng(3)
    for k in range(300):
        t = station.period * (k + 1)
        q = 0.3 * np.sin(0.01 * k + np.arange(N))
        v = 0.3 * 0.01 / station.period * np.cos(0.01 * k + np.arange(N))
        station.lcm.publish(hardware.joint_state_channel,
                            encode_joint_state("iiwa_status", t, q, v))
        w = rng.normal(size=6) + (np.r_[0, 0, 30.0, 0, 0, 0] if 150 <= k < 250 else 0)
        station.lcm.publish(hardware.ft_channel, encode_wrench(t, w))
        station.spin_once(0)
    station.lcm.handle(0)
    return model, scenario, station, recorder.to_frame(), got


def test_a_live_station_records_its_outputs_and_replay_reproduces_them(live_run):
    model, scenario, station, log, _ = live_run
    chain_columns = [c for o in col.CHAIN_OUTPUTS for c in o.columns]
    assert list(log.columns) == [col.TIME, *col.joint_columns(col.Q), *col.joint_columns(col.QD),
                                 *col.wrench_columns(col.MEASURED), *chain_columns]
    assert len(log) == station.processed == 300
    assert log[col.CONTACT].sum() > 50  # the 30 N step is detected
    replayed = ftdrake.replay(model, log, scenario)
    assert list(replayed.columns) == [col.TIME, *chain_columns]
    np.testing.assert_allclose(replayed[chain_columns].to_numpy(float),
                               log[chain_columns].to_numpy(float), rtol=0, atol=1e-12)


def test_the_lcm_station_publishes_what_it_records_under_the_same_names(live_run):
    _, _, station, log, got = live_run
    assert station.published == len(log)
    for port in ("wrench_contact", "wrench_compensated", "bias"):
        assert len(got[port]) == len(log)
        np.testing.assert_array_equal([m.t for m in got[port]], log[col.TIME])
        np.testing.assert_allclose([m.wrench for m in got[port]],
                                   log[list(col.OUTPUTS[port].columns)].to_numpy(), rtol=0,
                                   atol=1e-12)
    np.testing.assert_allclose([values for _, values in got["payload"]],
                               log[list(col.PAYLOAD)].to_numpy(), rtol=0, atol=1e-12)
    states = got["contact"]
    assert len(states) == len(log) and not any(s.fault for s in states)
    for name in ("contact", "contact_force", "out_of_domain", "payload_change"):
        np.testing.assert_array_equal([float(getattr(s, name)) for s in states],
                                      log[name].to_numpy(float), err_msg=name)


def test_a_log_of_the_earlier_release_reads_with_todays_names():
    path = DATA / "log_eb9851c.parquet"
    raw = pq.read_table(path).to_pandas()
    assert {"pred_Fx", "est_external_Fx", "detected", "contact", "internal_Fx"} <= set(raw)
    frame, _ = ftdrake.load_dataset(path)
    assert list(frame.columns) == [col.LEGACY_COLUMNS.get(c, c) for c in raw.columns]
    for old, new in zip(raw.columns, frame.columns, strict=True):
        np.testing.assert_array_equal(frame[new].to_numpy(), raw[old].to_numpy(), err_msg=new)
    # The flags by meaning: the detector's is `contact`, the plant's truth `contact_true`.
    np.testing.assert_array_equal(frame[col.CONTACT], raw["detected"])
    np.testing.assert_array_equal(frame[col.CONTACT_TRUE], raw["contact"])
    np.testing.assert_array_equal(frame[col.wrench_columns(col.BIAS)],
                                  raw[[f"bias_est_{a}" for a in col.WRENCH_AXES]])
    assert not (set(col.LEGACY_COLUMNS) - set(col.LEGACY_COLUMNS.values())) & set(frame.columns)
    # Today's readers take it: the compensation error against the truth, computed here on
    # the file's own columns under their old names.
    report = ftdrake.evaluate_detection(frame, ScenarioConfig().sensor.spec().noise_std)
    free = raw["contact"].to_numpy() == 0
    free[:2] = False  # evaluate_detection.STARTUP_SAMPLES
    error = (raw[[f"pred_{a}" for a in col.WRENCH_AXES]].to_numpy()
             - raw[[f"internal_{a}" for a in col.WRENCH_AXES]].to_numpy())[free]
    np.testing.assert_allclose(report["compensation_error_rms"],
                               np.sqrt(np.mean(error**2, axis=0)), rtol=1e-12)


def test_a_replay_csv_of_the_earlier_release_reads_with_todays_names():
    path = DATA / "replay_eb9851c.csv"
    raw = pd.read_csv(path)
    frame = read_frame(path)
    assert list(frame.columns) == [col.LEGACY_COLUMNS.get(c, c) for c in raw.columns]
    assert "detected" in raw and col.CONTACT in frame and col.CONTACT_TRUE not in frame
    np.testing.assert_array_equal(frame.to_numpy(), raw.to_numpy())


def test_a_log_written_now_keeps_its_names(tmp_path):
    rng = np.random.default_rng(0)
    frame = pd.DataFrame({col.TIME: np.arange(5) * 0.001, col.CONTACT: [0, 1, 1, 0, 0],
                          **{c: rng.normal(size=5) for c in col.wrench_columns("wrench_contact")}})
    for name in ("log.parquet", "log.csv"):
        write_log(frame, tmp_path / name)
        back = read_frame(tmp_path / name)
        assert list(back.columns) == list(frame.columns), name
        np.testing.assert_allclose(back.to_numpy(float), frame.to_numpy(float))
    metadata = pq.read_schema(tmp_path / "log.parquet").metadata
    assert metadata[b"ftdrake.log_format"] == str(col.LOG_FORMAT).encode() == b"2"
    # Only the version tells a lone `contact` apart: format 1's is the truth.
    assert col.legacy_renames([col.CONTACT], 1) == {col.CONTACT: col.CONTACT_TRUE}
    assert col.legacy_renames([col.CONTACT], None) == {}


def test_the_docs_render_the_table_as_conventions_defines_it():
    spec = importlib.util.spec_from_file_location("signal_table",
                                                  ROOT / "docs/hooks/signal_table.py")
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    page = (ROOT / "docs/guide/logs.md").read_text()
    assert hook.MARKER in page
    rendered = hook.on_page_markdown(page, None, None, None)
    table = col.signal_table_markdown()
    assert table in rendered and hook.MARKER not in rendered
    rows = table.splitlines()[2:]
    assert len(rows) == len(col.CHAIN_OUTPUTS)
    for row, o in zip(rows, col.CHAIN_OUTPUTS, strict=True):
        assert row.startswith(f"| `{o.port}` | {o.size} | `{o.columns[0]}`")
        assert (o.lcm_channel or "–") in row and (o.ros2 or "–").rpartition(".")[2] in row
