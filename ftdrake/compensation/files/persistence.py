"""Saving and loading fitted compensators without running code from the file.

A pickle runs whatever code its author chose when it is loaded. A model file here instead
holds a skops payload (a zip of JSON and numpy arrays) that is rebuilt only from the types
on an explicit list, inside an envelope that records what the model is::

    FTDRAKE-MODEL\\n                  magic line
    {"format_version": 2, ...}\\n    manifest: one line of JSON (read it with `head -2`)
    <payload_bytes bytes>            skops payload
    <32 bytes>                       SHA-256 of everything above

The manifest names the model class, the joint count, the feature set, target names and
units, the sensor frame, the training range of every input column, the ftdrake and
scikit-learn versions, and the payload's size and SHA-256. A model built on a robot file
carries the robot's text and keeps only the file's name, not the folder it was in. The
checksums catch corruption, truncation and careless edits; they are not a signature (anyone
can recompute them), which is why loading also refuses types off the list and checks every
decision tree's node indices.

Every problem with a file raises :class:`ModelFileError` naming it. Files written before
``compensation/`` was split into sub-packages name their types by the old module paths; they
are read through :mod:`.moved_names`'s table.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import warnings
import zipfile
from pathlib import Path

import numpy as np
import sklearn
import skops.io as sio
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from ...conventions import IMU_INPUTS, TEMPERATURE, WRENCH_AXES, WRENCH_UNITS
from ...errors import ConfigError, ModelFileError, RobotModelError
from ...io import atomic_write_bytes
from ...version import ftdrake_version
from ..estimators.base import Compensator
from ..estimators.build import is_wrench
from ..estimators.motion_std import MotionStdCompensator
from ..estimators.registry import trusted_types
from ..estimators.robot_file import CarriesRobot, file_name_only
from ..features import feature_names
from .moved_names import current_name, current_payload

MAGIC = b"FTDRAKE-MODEL\n"
# 2: the physics model takes a robot description instead of embedding a scenario; the
# trusted types come from the compensator registry. 3: a model built on a robot carries the
# robot's text (compensation.estimators.robot_file) and the manifest its SHA-256. Version 2 files
# still load: their robot is embedded on loading when its path is there.
FORMAT_VERSION = 3
READABLE_VERSIONS = (2, 3)
_DIGEST = 32  # bytes of SHA-256
#: What a model file holds: a compensator, or one with a std of the motion around it.
SAVABLE = (Compensator, MotionStdCompensator)



# -- saving -------------------------------------------------------------------------------
def save_model(
    model: Compensator,
    path,
    *,
    target_names=None,
    target_units=None,
    sensor_frame: str = "S",
    extra: dict | None = None,
) -> Path:
    """Writes fitted `model` to `path` atomically; returns the path.

    `target_names`/`target_units` give one name and unit per output column. For a model of
    6 outputs they default to a wrench, ``Fx … Tz`` in N and N·m
    (``conventions.WRENCH_AXES``/``WRENCH_UNITS``); given wrench names (``meas_Fx`` …) take
    those units by default too. Any other model needs both. `sensor_frame` names the frame
    the targets are expressed in; `extra` is any JSON-serialisable dict kept in the manifest.
    """
    target_names, target_units = _default_targets(model, target_names, target_units)
    with _robot_file_names_only(model):
        manifest = _manifest(model, target_names, target_units, sensor_frame, extra)
        payload = sio.dumps(model, compression=zipfile.ZIP_DEFLATED)
    # Refuse to write a file that load_model would refuse to read.
    untrusted = _untrusted(payload)
    if untrusted:
        raise ValueError(
            f"model contains types the model-file loader does not trust: {untrusted}; "
            "register them in ftdrake/compensation/estimators/registry.py"
        )
    manifest["payload_bytes"] = len(payload)
    manifest["payload_sha256"] = hashlib.sha256(payload).hexdigest()
    path = Path(path)
    atomic_write_bytes(path, _pack(manifest, payload))
    return path


def _default_targets(model, target_names, target_units) -> tuple[list, list]:
    """The names and units a model is saved with (see :func:`save_model`)."""
    n = getattr(model, "n_outputs_", None)
    if target_names is None and n == len(WRENCH_AXES):
        target_names = list(WRENCH_AXES)
    if target_names is None:
        raise ConfigError(f"save_model: a model of {n} outputs (not a wrench) needs "
                          "target_names=[one name per output] and target_units=[...]")
    if target_units is None and is_wrench(list(target_names)):
        target_units = list(WRENCH_UNITS)
    if target_units is None:
        raise ConfigError(f"save_model: target_units=[one unit per output] is needed for "
                          f"targets {list(target_names)} (a wrench's default to N and N*m)")
    return list(target_names), list(target_units)


def _manifest(model, target_names, target_units, sensor_frame, extra) -> dict:
    if not isinstance(model, SAVABLE):
        raise TypeError(f"expected a Compensator; got {type(model).__name__}")
    check_is_fitted(model)
    if _qualified_name(type(model)) not in trusted_types():
        raise ValueError(f"{_qualified_name(type(model))} is not a registered compensator; "
                         "add it to ftdrake/compensation/estimators/registry.py")
    target_names = [str(t) for t in target_names]
    target_units = [str(u) for u in target_units]
    if not len(target_names) == len(target_units) == model.n_outputs_:
        raise ValueError(
            f"model has {model.n_outputs_} outputs but {len(target_names)} target names and "
            f"{len(target_units)} target units"
        )
    inputs = feature_names("q,qd,qdd", model.n_joints_)
    if getattr(model, "needs_imu", False):
        inputs.extend(IMU_INPUTS)  # after [q, q̇, q̈]: the IMU model's nine columns
    if getattr(model, "temperature_in_", False):
        inputs.append(TEMPERATURE)  # X's last column, °C: its range is kept like the others'
    manifest = {
        "format_version": FORMAT_VERSION,
        "model_class": _qualified_name(type(model)),
        "ftdrake_version": ftdrake_version(),
        "sklearn_version": sklearn.__version__,
        "n_joints": int(model.n_joints_),
        "features": model.features,
        "n_outputs": int(model.n_outputs_),
        "target_names": target_names,
        "target_units": target_units,
        "sensor_frame": str(sensor_frame),
        "input_range": {
            name: [float(lo), float(hi)]
            for name, lo, hi in zip(inputs, model.input_min_, model.input_max_, strict=True)
        },
        "robot": _robot_manifest(model),
        "extra": extra or {},
    }
    try:
        json.dumps(manifest, allow_nan=False)
    except (TypeError, ValueError) as e:
        raise ValueError(f"extra must be JSON-serialisable (finite numbers): {e}") from None
    return manifest


def _pack(manifest: dict, payload: bytes) -> bytes:
    line = json.dumps(manifest, allow_nan=False, separators=(",", ":")).encode() + b"\n"
    body = MAGIC + line + payload
    return body + hashlib.sha256(body).digest()


def read_manifest(path) -> dict:
    """The manifest of the model file at `path`, after checking the file's integrity."""
    manifest, _ = _unpack(Path(path).read_bytes(), path)
    return manifest


def load_model(path, *, expect_n_joints: int | None = None, expect_features: str | None = None):
    """Loads a compensator saved by :func:`save_model`; raises ModelFileError on any problem.

    `expect_n_joints` / `expect_features`: refuse a model made for another robot or feature
    set. The manifest (target names, units, frame, ranges) is available via
    :func:`read_manifest`.
    """
    manifest, payload = _unpack(Path(path).read_bytes(), path)
    _check_expectations(manifest, path, expect_n_joints, expect_features)
    payload = current_payload(payload)  # a file from before the split names old module paths
    untrusted = _untrusted(payload)
    if untrusted:
        raise ModelFileError(f"{path}: refusing to load types no registered compensator "
                             f"uses: {untrusted}")
    if manifest.get("sklearn_version") != sklearn.__version__:
        warnings.warn(
            f"{path} was saved with scikit-learn {manifest.get('sklearn_version')}, loading "
            f"with {sklearn.__version__}; check its predictions",
            stacklevel=2,
        )
    try:
        model = sio.loads(payload, trusted=list(trusted_types()))
    except Exception as e:  # whatever skops raises, the file is at fault
        raise ModelFileError(f"{path}: payload could not be rebuilt: {e}") from e
    _check_model(model, manifest, path)
    _check_robot(model, manifest, path)
    return model


def _robot_parts(model) -> list:
    """The parts of `model` built on a robot (a hybrid's physics part, or the model)."""
    inner = getattr(model, "estimator_", None)  # a MotionStdCompensator's mean
    return [part for part in (model, getattr(model, "physics_", None), inner,
                              getattr(inner, "physics_", None))
            if isinstance(part, CarriesRobot)]


@contextlib.contextmanager
def _robot_file_names_only(model):
    """Within the block, every part of `model` that embeds its robot's text names its robot
    file by the file's name alone
    (:func:`~ftdrake.compensation.estimators.robot_file.file_name_only`), as the file then stores
    it; restored after."""
    changed = []
    for part in _robot_parts(model):
        if getattr(part, "robot_model_", None) is not None:
            name = file_name_only(part.robot)
            if name != part.robot:
                changed.append((part, part.robot))
                part.robot = name
    try:
        yield
    finally:
        for part, robot in changed:
            part.robot = robot


def _robot_manifest(model) -> dict | None:
    parts = _robot_parts(model)
    if not parts:
        return None
    part = parts[0]
    return {"source": None if part.robot is None else str(part.robot),
            "sha256": part.robot_digest(),
            "portable": bool(getattr(part, "robot_portable_", True))}


def _check_robot(model, manifest: dict, path) -> None:
    """The robot the model needs can be built here, from what the file carries."""
    expected = (manifest.get("robot") or {}).get("sha256")
    for part in _robot_parts(model):
        if expected is not None and part.robot_digest() != expected:
            raise ModelFileError(f"{path}: the embedded robot does not match the manifest's "
                                 "SHA-256")
        try:
            notes = part.check_robot()
        except RobotModelError as e:
            raise ModelFileError(f"{path}: {e}") from None
        for note in notes:
            warnings.warn(f"{path}: {note}", stacklevel=3)


def _unpack(data: bytes, path) -> tuple[dict, bytes]:
    """Verifies the envelope; returns (manifest, payload)."""
    if not data.startswith(MAGIC):
        raise ModelFileError(f"{path}: not an ftdrake model file (no {MAGIC[:-1].decode()} line)")
    manifest, header_end = _parse_manifest(data)
    if len(data) < len(MAGIC) + _DIGEST or (
        hashlib.sha256(data[:-_DIGEST]).digest() != data[-_DIGEST:]
    ):
        expected = _expected_size(manifest, header_end)
        if expected is not None and len(data) < expected:
            raise ModelFileError(f"{path}: truncated ({len(data)} of {expected} bytes)")
        raise ModelFileError(f"{path}: checksum mismatch; the file is corrupted or was modified")
    if manifest is None:
        raise ModelFileError(f"{path}: manifest line is not valid JSON")
    if manifest.get("format_version") not in READABLE_VERSIONS:
        version = manifest.get("format_version")
        older = isinstance(version, int) and version < FORMAT_VERSION
        raise ModelFileError(
            f"{path}: model file format version {version!r} is not supported (this ftdrake "
            f"{ftdrake_version()} reads versions {', '.join(map(str, READABLE_VERSIONS))}); "
            + ("it was written by an older ftdrake: train the model again (ftdrake train)"
               if older else "it was written by a newer ftdrake: upgrade ftdrake")
        )
    payload = data[header_end:-_DIGEST]
    if len(payload) != manifest.get("payload_bytes"):
        raise ModelFileError(
            f"{path}: payload is {len(payload)} bytes, manifest says "
            f"{manifest.get('payload_bytes')}"
        )
    if hashlib.sha256(payload).hexdigest() != manifest.get("payload_sha256"):
        raise ModelFileError(f"{path}: payload SHA-256 does not match the manifest")
    return manifest, payload


def _parse_manifest(data: bytes) -> tuple[dict | None, int]:
    """(manifest or None if unreadable, offset of the payload)."""
    end = data.find(b"\n", len(MAGIC))
    if end < 0:
        return None, len(data)
    try:
        manifest = json.loads(data[len(MAGIC) : end])
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None, end + 1
    return (manifest if isinstance(manifest, dict) else None), end + 1


def _expected_size(manifest: dict | None, header_end: int) -> int | None:
    size = manifest.get("payload_bytes") if manifest else None
    return header_end + size + _DIGEST if isinstance(size, int) else None


def _check_expectations(manifest, path, expect_n_joints, expect_features) -> None:
    if expect_n_joints is not None and manifest.get("n_joints") != expect_n_joints:
        raise ModelFileError(
            f"{path}: model is for {manifest.get('n_joints')} joints, expected {expect_n_joints}"
        )
    if expect_features is not None and manifest.get("features") != expect_features:
        raise ModelFileError(
            f"{path}: model uses features {manifest.get('features')!r}, "
            f"expected {expect_features!r}"
        )


def _check_model(model, manifest: dict, path) -> None:
    """The rebuilt object is the model the manifest describes, and its trees are sound."""
    name = _qualified_name(type(model))
    if (name != current_name(str(manifest.get("model_class")))
            or not isinstance(model, SAVABLE)):
        raise ModelFileError(
            f"{path}: payload holds {name}, manifest says {manifest.get('model_class')}"
        )
    for attr, key in (
        ("n_joints_", "n_joints"),
        ("features", "features"),
        ("n_outputs_", "n_outputs"),
    ):
        if getattr(model, attr, None) != manifest.get(key):
            raise ModelFileError(
                f"{path}: model's {attr} is {getattr(model, attr, None)!r}, "
                f"manifest says {manifest.get(key)!r}"
            )
    try:
        _check_trees(model)
    except (AttributeError, TypeError, ValueError) as e:
        raise ModelFileError(f"{path}: unsound decision tree: {e}") from None


def _check_trees(model) -> None:
    """Every tree's node indices stay inside its node array and its owner's input columns.

    A forest hands its trees the X it validated against its own ``n_features_in_``, and a
    lone tree validates against its own; so each owner's ``n_features_in_`` bounds the split
    features. Children are always created after their parent, so a child index above its
    parent's also rules out cycles.
    """
    for owner in _estimators_in(model):
        state = vars(owner)
        if "tree_" in state:
            trees = [state["tree_"]]
        else:
            trees = [
                vars(e)["tree_"]
                for e in state.get("estimators_", ())
                if isinstance(e, BaseEstimator) and "tree_" in vars(e)
            ]
        for tree in trees:
            _check_tree(tree, int(owner.n_features_in_))


def _check_tree(tree, n_features: int) -> None:
    n = int(tree.node_count)
    node = np.arange(n)
    left, right, feature = (
        np.asarray(a)[:n] for a in (tree.children_left, tree.children_right, tree.feature)
    )
    if len(left) != n or len(right) != n or len(feature) != n:
        raise ValueError("node arrays shorter than node_count")
    leaf = left == -1
    split = ~leaf
    sound = (
        np.all(right[leaf] == -1)
        and np.all((left[split] > node[split]) & (left[split] < n))
        and np.all((right[split] > node[split]) & (right[split] < n))
        and np.all((feature[split] >= 0) & (feature[split] < n_features))
    )
    if not sound:
        raise ValueError(f"node indices out of range (tree of {n} nodes, {n_features} features)")


def _estimators_in(obj):
    """Every scikit-learn estimator reachable through attributes, lists, tuples and dicts."""
    if isinstance(obj, BaseEstimator):
        yield obj
        children = vars(obj).values()
    elif isinstance(obj, (list, tuple)):
        children = obj
    elif isinstance(obj, dict):
        children = obj.values()
    else:
        return
    for child in children:
        yield from _estimators_in(child)


def _untrusted(payload: bytes) -> list[str]:
    try:
        found = sio.get_untrusted_types(data=payload)
    except Exception as e:  # an unreadable payload is a bad file, whatever the reason
        raise ModelFileError(f"payload is not a readable skops archive: {e}") from e
    return sorted(t for t in found if t not in trusted_types())


# -- helpers ------------------------------------------------------------------------------
def _qualified_name(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"
