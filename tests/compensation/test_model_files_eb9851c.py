"""Model files written before ``compensation/`` was split into sub-packages still load.

tests/data/model_kinds_eb9851c/ holds one small model of every kind a model file may hold,
saved by the code at commit eb9851c (make_models.py there says how), whose files name their
classes by the old module paths (``ftdrake.compensation.forest.RandomForestCompensator``), and
what that code predicted for a few rows. Loaded with today's code, each is today's class and
predicts the same numbers.
"""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest

from ftdrake.compensation.estimators.registry import trusted_types
from ftdrake.compensation.files.moved_names import MOVED_MODULES, current_name, current_payload
from ftdrake.compensation.files.persistence import load_model, read_manifest
from tests.helpers import DATA

FOLDER = DATA / "model_kinds_eb9851c"
NAMES = ("forest", "svr", "gpr", "per_output", "physics", "hybrid", "arm", "orientation")


@pytest.fixture(scope="module")
def predictions():
    with np.load(FOLDER / "predictions.npz") as saved:
        return dict(saved)


def test_every_kind_of_model_is_there():
    assert sorted(p.stem for p in FOLDER.glob("*.ftd")) == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_an_old_file_loads_as_todays_class_and_predicts_the_same(name, predictions):
    path = FOLDER / f"{name}.ftd"
    old_class = read_manifest(path)["model_class"]
    assert old_class.rpartition(".")[0] in MOVED_MODULES  # the file names an old module path
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no note: same scikit-learn, the robot is embedded
        model = load_model(path)
    cls = type(model)
    assert f"{cls.__module__}.{cls.__qualname__}" == current_name(old_class) != old_class
    X = predictions[f"X_{name}"]
    np.testing.assert_allclose(model.predict(X), predictions[f"mean_{name}"], rtol=1e-12,
                               atol=1e-12)
    np.testing.assert_allclose(model.predict_std(X), predictions[f"std_{name}"], rtol=1e-12,
                               atol=1e-12)


def test_every_moved_module_is_where_the_table_says_and_its_types_are_trusted():
    trusted = set(trusted_types())
    for old, new in MOVED_MODULES.items():
        module = importlib.import_module(new)
        moved = [t for t in trusted if t.rpartition(".")[0] == new]
        assert moved, f"{old} → {new}: no trusted type lives there"
        assert all(hasattr(module, t.rpartition(".")[2]) for t in moved)
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(old)  # no alias module: only the loader reads old names


def test_a_payload_naming_no_moved_module_is_passed_through_unchanged():
    assert current_payload(b"not a zip") == b"not a zip"
    assert current_name("sklearn.tree._tree.Tree") == "sklearn.tree._tree.Tree"
