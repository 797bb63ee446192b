"""Model files: round trip, manifest, and refusal of corrupt, unsafe or mismatched files."""

from __future__ import annotations

import hashlib
import json
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
import skops.io as sio
from hypothesis import given, settings
from hypothesis import strategies as st

from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.gpr import GPRCompensator
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.compensation.estimators.svr import SVRCompensator
from ftdrake.compensation.estimators.tuning import PerOutputCompensator
from ftdrake.compensation.files import persistence
from ftdrake.compensation.files.persistence import (
    ModelFileError,
    load_model,
    read_manifest,
    save_model,
)
from ftdrake.conventions import WRENCH_AXES, WRENCH_UNITS

N_JOINTS = 7


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(150, 3 * N_JOINTS))
    Y = np.column_stack([np.sin(X[:, j]) * (10 if j < 3 else 0.5) for j in range(6)])
    return X, Y


def save(model, path, **kw):
    return save_model(model, path, target_names=WRENCH_AXES, target_units=WRENCH_UNITS, **kw)


@pytest.fixture(scope="module")
def forest_file(data, tmp_path_factory):
    X, Y = data
    model = RandomForestCompensator(features="q,qd", n_estimators=3, random_state=0).fit(X, Y)
    path = save(model, tmp_path_factory.mktemp("models") / "forest.ftdm", extra={"run": 7})
    return model, path


# -- round trip ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "make",
    [
        lambda: RandomForestCompensator(n_estimators=3, random_state=0),
        lambda: RandomForestCompensator(n_estimators=3, per_output=False, random_state=0),
        lambda: SVRCompensator(features="q"),
        lambda: PerOutputCompensator([SVRCompensator(C=c) for c in (1, 2, 3, 4, 5, 6)]),
        # Other engineers' compensators, registered in the registry by one line each.
        lambda: GPRCompensator(max_points=100, optimize_points=50, random_state=0),
        lambda: PhysicsPayloadCompensator(),
        lambda: HybridCompensator(residual=RandomForestCompensator(n_estimators=3, random_state=0)),
    ],
    ids=["rf", "rf_multi", "svr", "per_output", "gpr", "physics", "hybrid"],
)
@pytest.mark.filterwarnings("ignore:the data does not excite")  # physics on random data
def test_round_trip_predicts_identically(make, data, tmp_path):
    X, Y = data
    model = make().fit(X, Y)
    loaded = load_model(save(model, tmp_path / "m.ftdm"))
    assert type(loaded) is type(model)
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))
    np.testing.assert_array_equal(loaded.predict_std(X), model.predict_std(X))
    assert loaded.get_params(deep=False).keys() == model.get_params(deep=False).keys()


def test_manifest_describes_the_model(forest_file, data):
    model, path = forest_file
    manifest = read_manifest(path)
    assert manifest["model_class"] == ("ftdrake.compensation.estimators.forest."
                                       "RandomForestCompensator")
    assert manifest["n_joints"] == N_JOINTS and manifest["features"] == "q,qd"
    assert manifest["target_names"] == list(WRENCH_AXES)
    assert manifest["target_units"] == list(WRENCH_UNITS)
    assert manifest["sensor_frame"] == "S" and manifest["extra"] == {"run": 7}
    assert len(manifest["input_range"]) == 3 * N_JOINTS
    assert manifest["input_range"]["qd_2"] == [model.input_min_[9], model.input_max_[9]]
    assert manifest["ftdrake_version"] and manifest["sklearn_version"]
    # The manifest is the second line of the file, readable without ftdrake.
    assert json.loads(path.read_bytes().split(b"\n")[1]) == manifest


def test_expectations_that_match_load(forest_file, data):
    model, path = forest_file
    dut = load_model(path, expect_n_joints=N_JOINTS, expect_features="q,qd")
    assert type(dut) is RandomForestCompensator
    assert dut.n_joints_ == N_JOINTS and dut.features == "q,qd"
    X, _ = data
    np.testing.assert_array_equal(dut.predict(X), model.predict(X))


# -- refusals --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"expect_n_joints": 6}, "model is for 7 joints, expected 6"),
        ({"expect_features": "q"}, "features 'q,qd', expected 'q'"),
    ],
)
def test_mismatched_model_is_refused(forest_file, kwargs, match):
    with pytest.raises(ModelFileError, match=match):
        load_model(forest_file[1], **kwargs)


@settings(max_examples=40, deadline=None)
@given(where=st.floats(0, 1, exclude_max=True), bit=st.integers(0, 7))
def test_a_flipped_bit_anywhere_is_refused(forest_file, tmp_path_factory, where, bit):
    _, path = forest_file
    data = bytearray(path.read_bytes())
    data[int(where * len(data))] ^= 1 << bit
    bad = tmp_path_factory.mktemp("flipped") / "m.ftdm"
    bad.write_bytes(bytes(data))
    with pytest.raises(ModelFileError):
        load_model(bad)


@pytest.mark.parametrize("keep", [0, 5, 60, 0.5, -1])
def test_a_truncated_file_is_refused(forest_file, tmp_path, keep):
    _, path = forest_file
    data = path.read_bytes()
    cut = data[: int(keep * len(data)) if isinstance(keep, float) else keep]
    (tmp_path / "m.ftdm").write_bytes(cut)
    with pytest.raises(ModelFileError):
        load_model(tmp_path / "m.ftdm")


def test_truncation_is_named(forest_file, tmp_path):
    data = forest_file[1].read_bytes()
    (tmp_path / "m.ftdm").write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelFileError, match=rf"truncated \({len(data) // 2} of {len(data)}"):
        load_model(tmp_path / "m.ftdm")


def test_other_files_are_refused(tmp_path):
    import pickle

    (tmp_path / "m.pkl").write_bytes(pickle.dumps({"a": 1}))
    with pytest.raises(ModelFileError, match="not an ftdrake model file"):
        load_model(tmp_path / "m.pkl")


def repack(manifest: dict, payload: bytes) -> bytes:
    """What an attacker can do: a well-formed envelope with matching checksums."""
    manifest = {
        **manifest,
        "payload_bytes": len(payload),
        "payload_sha256": hashlib.sha256(payload).hexdigest(),
    }
    return persistence._pack(manifest, payload)


class Evil:
    """Its __setstate__ would run on load if the type were trusted."""

    ran = False

    def __setstate__(self, state):
        Evil.ran = True


def test_untrusted_type_is_refused_without_running_it(forest_file, tmp_path):
    model, path = forest_file
    model.evil_ = Evil()
    try:
        payload = sio.dumps(model)
    finally:
        del model.evil_
    (tmp_path / "m.ftdm").write_bytes(repack(read_manifest(path), payload))
    evil = re.escape(f"{Evil.__module__}.Evil")  # as pytest named this module
    with pytest.raises(ModelFileError, match=rf"no registered compensator uses: \['{evil}'"):
        load_model(tmp_path / "m.ftdm")
    assert not Evil.ran


def test_tree_with_out_of_range_node_index_is_refused(data, tmp_path):
    # sklearn follows tree node indices unchecked: a crafted index could crash predict().
    X, Y = data
    model = RandomForestCompensator(n_estimators=2, random_state=0).fit(X, Y)
    path = save(model, tmp_path / "good.ftdm")
    tree = model.forests_[0].estimators_[1].tree_
    state = tree.__getstate__()
    state["nodes"]["left_child"][0] = 10**6
    tree.__setstate__(state)
    (tmp_path / "bad.ftdm").write_bytes(repack(read_manifest(path), sio.dumps(model)))
    with pytest.raises(ModelFileError, match="unsound decision tree"):
        load_model(tmp_path / "bad.ftdm")


def test_payload_of_another_class_is_refused(forest_file, data, tmp_path):
    X, Y = data
    payload = sio.dumps(SVRCompensator().fit(X, Y))
    (tmp_path / "m.ftdm").write_bytes(repack(read_manifest(forest_file[1]), payload))
    with pytest.raises(ModelFileError, match=r"payload holds .*SVRCompensator"):
        load_model(tmp_path / "m.ftdm")


def test_other_sklearn_version_warns(forest_file, tmp_path):
    model, path = forest_file
    manifest = {**read_manifest(path), "sklearn_version": "0.1"}
    (tmp_path / "m.ftdm").write_bytes(
        repack(manifest, sio.dumps(model, compression=zipfile.ZIP_DEFLATED))
    )
    with pytest.warns(UserWarning, match="scikit-learn 0.1"):
        load_model(tmp_path / "m.ftdm")


@pytest.mark.parametrize("version, says", [(1, "older ftdrake: train the model again"),
                                           (99, "newer ftdrake: upgrade")])
def test_other_format_versions_are_refused_naming_the_version(forest_file, tmp_path, version,
                                                              says):
    model, path = forest_file
    manifest = {**read_manifest(path), "format_version": version}
    (tmp_path / "m.ftdm").write_bytes(
        repack(manifest, sio.dumps(model, compression=zipfile.ZIP_DEFLATED))
    )
    with pytest.raises(ModelFileError, match=rf"format version {version} .*{says}"):
        load_model(tmp_path / "m.ftdm")


# -- saving ----------------------------------------------------------------------------------
def test_save_replaces_atomically_and_leaves_no_temporary_files(data, tmp_path):
    X, Y = data
    path = tmp_path / "m.ftdm"
    save(SVRCompensator().fit(X, Y), path)
    first = path.read_bytes()
    with pytest.raises(ValueError):  # a failed save leaves the old file untouched
        save_model(SVRCompensator().fit(X, Y), path, target_names=["a"], target_units=["N"])
    assert path.read_bytes() == first
    save(SVRCompensator(C=3.0).fit(X, Y), path)
    assert load_model(path).C == 3.0
    assert [p.name for p in Path(tmp_path).iterdir()] == ["m.ftdm"]


def test_save_refuses_what_it_cannot_describe(data, tmp_path):
    X, Y = data
    fitted = SVRCompensator().fit(X, Y)
    with pytest.raises(Exception, match="not fitted"):
        save(SVRCompensator(), tmp_path / "m")
    with pytest.raises(ValueError, match="6 outputs but 6 target names and 5"):
        save_model(fitted, tmp_path / "m", target_names=WRENCH_AXES, target_units=["N"] * 5)
    with pytest.raises(ValueError, match="JSON"):
        save(fitted, tmp_path / "m", extra={"when": object()})
    with pytest.raises(TypeError, match="Compensator"):
        save(object(), tmp_path / "m")
