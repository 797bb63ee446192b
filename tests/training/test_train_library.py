"""Training as a library call (`ftdrake.train`), the stream delay as a fit parameter, the
domain calibration as a wrapping estimator, and model files of the previous release."""

from __future__ import annotations

import ast
import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.utils.validation import check_is_fitted

import ftdrake
from ftdrake.cli.main import main as cli_main
from ftdrake.compensation.estimators import domain
from ftdrake.compensation.estimators.tuning import tune
from ftdrake.compensation.files.persistence import load_model, read_manifest
from ftdrake.data.training import ReadOptions
from ftdrake.errors import ConfigError
from tests.helpers import DATA

UR3_ID1 = DATA / "ur3" / "id1.csv"
TORQUES = ReadOptions(targets="tau_*", velocities="qd_*")
# Written by `ftdrake train` at eb9851c (the release before the training pipeline became a
# library call) on 3 one-second Fourier runs of the simulated arm (--max-rows 1200):
# hyb_cal: --kind hybrid --domain-calibration (a fourth run) --domain-shared-growth
# --delay 0.004; hyb_hold: --kind hybrid --domain-holdout 0.3 --domain-level held_out --align;
# phys: --kind physics --align. predictions.npz: rows X of the fourth run and each model's
# predict / predict_std / wrench_delay_s_ there, computed by that release.
OLD_MODELS = DATA / "models_eb9851c"


@pytest.mark.parametrize("name", ["hyb_cal", "hyb_hold", "phys"])
def test_model_files_of_the_previous_release_load_and_predict_the_same(name):
    expected = np.load(OLD_MODELS / "predictions.npz")
    model = load_model(OLD_MODELS / f"{name}.ftd")
    X = expected["X"]
    np.testing.assert_allclose(model.predict(X), expected[f"{name}_mean"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(model.predict_std(X), expected[f"{name}_std"], rtol=0,
                               atol=1e-12)
    mean, std = model.row_predictor()(X[3])
    np.testing.assert_allclose(mean, expected[f"{name}_mean"][3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(std, expected[f"{name}_std"][3], rtol=0, atol=1e-12)
    assert model.wrench_delay_s_ == float(expected[f"{name}_delay"]) > 0
    assert ftdrake.CompensationChain(model).delay_line is not None  # the chain reads it


# -- the library call -------------------------------------------------------------------------
def test_the_library_call_trains_what_the_command_line_trains(tmp_path, capsys):
    """The same options as flags and as TrainOptions: the same model (to the last bit) and
    the same provenance in its file; a DataFrame of the file's table: the same model too."""
    out = tmp_path / "cli.ftd"
    assert cli_main(["train", "--data", str(UR3_ID1), "--targets", "tau_*", "--velocities",
                     "qd_*", "--kind", "rf", "--preset", "none", "--max-rows", "400",
                     "--delay", "0.008", "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    options = ftdrake.TrainOptions(kind="rf", preset="none", max_rows=400, delay_s=0.008,
                                   read=TORQUES)
    result = ftdrake.train(UR3_ID1, options)
    X = ftdrake.load_training_data(UR3_ID1, TORQUES).X
    from_cli = load_model(out)
    np.testing.assert_array_equal(result.model.predict(X), from_cli.predict(X))
    assert result.model.wrench_delay_s_ == from_cli.wrench_delay_s_ == 0.008
    manifest = read_manifest(out)
    assert json.loads(json.dumps(result.provenance)) == manifest["extra"]
    assert result.provenance["subsample"]["rows_used"] == 400
    assert result.provenance["stream_delay"] == {"delay_s": 0.008, "given": True}
    assert result.target_names == manifest["target_names"]
    assert result.target_units == manifest["target_units"] == ["N*m"] * 6
    # Keywords are TrainOptions' fields; a table in memory reads as its file does.
    frame = ftdrake.train(pd.read_csv(UR3_ID1), kind="rf", preset="none", max_rows=400,
                          delay_s=0.008, read=TORQUES)
    np.testing.assert_array_equal(frame.model.predict(X), from_cli.predict(X))
    assert frame.provenance["data"]["file"] == "DataFrame"
    saved = frame.save(tmp_path / "frame.ftd")
    np.testing.assert_array_equal(load_model(saved).predict(X), from_cli.predict(X))


def test_progress_and_warnings_go_where_the_caller_says():
    lines, warned = [], []
    ftdrake.train(UR3_ID1, kind="rf", preset="none", read=TORQUES, t_start=4.0,
                  progress=lines.append, warn=warned.append)
    assert lines[0] == f"reading {UR3_ID1} …" and lines[-1].startswith("fitted in ")
    assert any("outside the time window" in line for line in lines)
    silent = ftdrake.train(UR3_ID1, kind="rf", preset="none", read=TORQUES)  # prints nothing
    assert silent.summary is None and silent.search is None


def test_messages_name_the_option_and_the_command_line_names_its_flag(tmp_path, capsys):
    with pytest.raises(ConfigError) as error:
        ftdrake.train(UR3_ID1, domain_shared_growth=True, read=TORQUES)
    assert str(error.value) == ("domain_shared_growth needs domain_holdout or "
                                "domain_calibration")
    with pytest.raises(ConfigError, match=r"^domain_holdout is for kind hybrid"):
        ftdrake.train(UR3_ID1, kind="rf", domain_holdout=0.2, read=TORQUES)
    with pytest.raises(ConfigError, match=r"^max_rows: must be a positive integer"):
        ftdrake.train(UR3_ID1, max_rows=0)
    with pytest.raises(ConfigError, match=r"^delay_s and align: "):
        ftdrake.train(UR3_ID1, delay_s=0.01, align=True)
    with pytest.raises(ConfigError, match=r"^kind physics on joint torques needs robot FILE"):
        ftdrake.train(UR3_ID1, kind="physics", read=ReadOptions(targets="tau_*"))
    code = cli_main(["train", "--data", str(UR3_ID1), "--targets", "tau_*", "--kind", "rf",
                     "--domain-shared-growth", "--out", str(tmp_path / "m.ftd")])
    assert code == 2 and capsys.readouterr().err.strip().endswith(
        "error: --domain-shared-growth needs --domain-holdout or --domain-calibration")


# -- the stream delay: a fit parameter ------------------------------------------------------------
def test_the_stream_delay_is_a_fit_parameter():
    rng = np.random.default_rng(0)
    X, Y = rng.normal(size=(200, 6)), rng.normal(size=(200, 3))
    forest = ftdrake.RandomForestCompensator(features="q", n_estimators=3, random_state=0)
    assert forest.fit(X, Y, wrench_delay_s=0.012).wrench_delay_s_ == 0.012
    assert forest.fit(X, Y).wrench_delay_s_ == 0.0  # each fit sets it: no delay given, none
    tuned, _ = tune(forest, X, Y, preset={"min_samples_leaf": [1, 5]}, cv="shuffled",
                    n_splits=2, progress=False, wrench_delay_s=-0.004)
    assert tuned.wrench_delay_s_ == -0.004
    with pytest.raises(ValueError, match="wrench_delay_s must be a finite"):
        forest.fit(X, Y, wrench_delay_s=float("nan"))


def test_no_fitted_attribute_is_written_from_outside_fit():
    """No module of the package assigns ``obj.name_`` (a fitted attribute) on anything but
    ``self``: fitted state is set in ``fit`` (scikit-learn's contract). The one exception
    builds a new fitted model from a copy of one (a correction applied to a physics model)."""
    allowed = {("compensation/estimators/physics.py", "with_correction")}
    package = Path(ftdrake.__file__).parent
    found = []
    for path in sorted(package.rglob("*.py")):
        module = path.relative_to(package).as_posix()
        for function, node in _assignments(ast.parse(path.read_text())):
            for target in getattr(node, "targets", [getattr(node, "target", None)]):
                if (isinstance(target, ast.Attribute) and target.attr.endswith("_")
                        and not target.attr.endswith("__")
                        and not (isinstance(target.value, ast.Name)
                                 and target.value.id == "self")
                        and (module, function) not in allowed):
                    found.append((module, function, node.lineno, ast.unparse(target)))
    assert not found, found


def _assignments(tree, function=""):
    """(the innermost enclosing function's name, node) of every assignment in `tree`."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield from _assignments(node, node.name)
            continue
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            yield function, node
        yield from _assignments(node, function)


# -- the domain calibration: a wrapping estimator -------------------------------------------------
@pytest.fixture(scope="module")
def runs():
    """Four 1 s Fourier runs of the simulated arm: three to fit on, one to calibrate on."""
    frame = ftdrake.collect(ftdrake.ScenarioConfig(), 4, kind="fourier", duration=1.0,
                            n_jobs=2, progress=False)
    X, Y = ftdrake.joint_state_layout(frame), ftdrake.wrench_targets(frame)
    fit, calibration = frame["trajectory"].to_numpy() < 3, frame["trajectory"].to_numpy() == 3
    return X[fit][::3], Y[fit][::3], X[calibration][::2], Y[calibration][::2]


@pytest.fixture(scope="module")
def hybrid(runs):
    X, Y, _, _ = runs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # excitation of 3 s of motion
        return ftdrake.HybridCompensator().fit(X, Y, wrench_delay_s=0.002)


def test_the_calibration_wraps_a_fitted_hybrid_and_leaves_it_as_it_was(runs, hybrid, tmp_path):
    _, _, Xc, Yc = runs
    state = {k: np.copy(v) if isinstance(v, np.ndarray) else v for k, v in vars(hybrid).items()
             if k.endswith("_") and not isinstance(v, dict)}
    unfitted = ftdrake.DomainCalibratedHybrid(hybrid, shared_growth=True)
    with pytest.raises(NotFittedError):
        check_is_fitted(unfitted)
    model = clone(unfitted).set_params(estimator=hybrid).fit(Xc, Yc)
    for k, v in state.items():  # the wrapped hybrid is as it was
        np.testing.assert_array_equal(getattr(hybrid, k), v, err_msg=k)
    assert model.estimator_ is hybrid and model.wrench_delay_s_ == 0.002
    terms = hybrid.domain_terms(Xc, Yc, shared_growth=True)
    assert model.domain_length_ == terms["length"] != hybrid.domain_length_
    np.testing.assert_array_equal(model.domain_growth_, terms["growth"])
    # The prediction and std, from the parts and the calibrated terms (module hybrid's
    # formulas): physics + w·residual, c‖BF‖² + w σ²_in + (1 − w) σ²_far + g² d.
    Z = Xc
    d = domain.distances(Z[:, :7], hybrid.domain_support_)
    w = np.exp(-(d / terms["length"]) ** 2)[:, None]
    mean = hybrid.physics_.predict(Z) + w * hybrid.residual_.predict(Z)
    np.testing.assert_allclose(model.predict(Z), mean, rtol=1e-12, atol=1e-12)
    physics_var = hybrid.physics_._variance(hybrid.physics_._select(Z), include_noise=False)
    var = (terms["parameter_scale"] * physics_var + w * terms["in_var"]
           + (1 - w) * hybrid.domain_far_var_ + terms["growth"] ** 2 * d[:, None])
    np.testing.assert_allclose(model.predict_std(Z), np.sqrt(var), rtol=1e-12, atol=1e-12)
    record = model.domain_calibration_
    assert record["rows"] == len(Xc) and record["shared_growth"]
    # Saved and loaded as itself; the chain reads the delay through it.
    ftdrake.save_model(model, tmp_path / "w.ftd")
    loaded = load_model(tmp_path / "w.ftd")
    assert type(loaded) is ftdrake.DomainCalibratedHybrid
    np.testing.assert_array_equal(loaded.predict(Z), model.predict(Z))
    np.testing.assert_allclose(loaded.row_predictor()(Z[5])[1], model.predict_std(Z[5:6])[0],
                               rtol=1e-12)
    assert ftdrake.CompensationChain(loaded).delay_line is not None


def test_the_loop_reads_the_wrapped_hybrids_training_range(runs, hybrid):
    """The chain's out-of-domain flag for the calibrated wrapper is the wrapped hybrid's: the
    loop contract reads the training range through the wrapper (the demo's hybrid is one)."""
    from ftdrake.compensation.contract import loop_view

    _, _, Xc, Yc = runs
    model = ftdrake.DomainCalibratedHybrid(hybrid, shared_growth=True).fit(Xc, Yc)
    view, wrapped = loop_view(model), loop_view(hybrid)
    assert view.lo.size == wrapped.lo.size == 3 * 7  # q, q̇, q̈ of 7 joints
    np.testing.assert_array_equal(view.lo, wrapped.lo)
    np.testing.assert_array_equal(view.hi, wrapped.hi)
    np.testing.assert_array_equal(view.lo, hybrid.input_min_[:view.lo.size])


def test_a_held_out_calibration_fits_clones_and_keeps_the_calibrated_terms(runs, hybrid):
    X, Y, _, _ = runs
    unfitted = ftdrake.HybridCompensator()
    groups = np.repeat(np.arange(3), -(-len(X) // 3))[:len(X)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ftdrake.DomainCalibratedHybrid(unfitted, holdout=0.3, in_domain="held_out").fit(
            X, Y, groups=groups, wrench_delay_s=0.001)
    assert not hasattr(unfitted, "physics_")  # the estimator given is a template
    record = model.domain_calibration_
    assert record["refit"] and record["training_rows"] + record["held_out_rows"] == len(X)
    assert model.domain_length_ == pytest.approx(record["length"] or np.inf)
    np.testing.assert_allclose(model.domain_growth_, record["growth"])
    # Refitted on all rows: the support is the whole data's; σ²_in = training error + excess.
    np.testing.assert_allclose(model.residual_noise_var_, model.estimator_.residual_training_var_
                               + model.domain_excess_var_)
    assert model.wrench_delay_s_ == model.estimator_.wrench_delay_s_ == 0.001


# -- what training says about the model -----------------------------------------------------------
def test_a_gp_says_how_many_rows_it_keeps_and_what_they_weigh(monkeypatch):
    """A GP keeps at most max_points rows (a covering subset); training says so, and how big
    the m × m factors its file holds are."""
    from ftdrake.compensation.estimators import registry

    monkeypatch.setitem(registry.entry("gpr").defaults, "max_points", 100)
    monkeypatch.setitem(registry.entry("gpr").defaults, "optimize_points", 0)
    lines = []
    result = ftdrake.train(UR3_ID1, kind="gpr", preset="none", read=TORQUES,
                           progress=lines.append)
    kept = [line for line in lines if line.startswith("the GP keeps")]
    n = len(result.data.X)
    factors = result.model.L_
    assert factors.shape == (6, 100, 100)  # one factor per output's kernel
    assert kept == [(f"the GP keeps 100 of the {n} rows (max_points 100: its fit costs m³, "
                     f"its file m² a kernel); its 6 Cholesky factors of 100 × 100 take "
                     f"{6 * 100 * 100 * 8 / 1e6:.1f} MB before compression")]
    monkeypatch.setitem(registry.entry("gpr").defaults, "max_points", 5000)
    lines.clear()
    ftdrake.train(UR3_ID1, kind="gpr", preset="none", read=TORQUES, progress=lines.append)
    assert not any(line.startswith("the GP keeps") for line in lines)  # it kept every row


@pytest.fixture(scope="module")
def physics_targets(runs):
    """The runs' rows with targets a payload model explains exactly, plus white noise: (the
    training rows, those targets plus a smooth effect on Fx that it cannot explain)."""
    X, Y, _, _ = runs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        physics = ftdrake.PhysicsPayloadCompensator().fit(X, Y)
    noise = 0.05 * np.random.default_rng(3).standard_normal(Y.shape)
    rigid = physics.predict(X) + noise
    cable = rigid.copy()
    cable[:, 0] += 1.5 * np.sin(3 * X[:, 0]) * np.cos(2 * X[:, 1])  # N, smooth in q
    names = [f"{block}_{j}" for block in ("q", "qd", "qdd") for j in range(7)]
    frame = pd.DataFrame(X, columns=names)  # the derivatives the targets were made with
    frame["t"] = np.arange(len(X)) * 3e-3
    return frame, rigid, cable


def _trained_on(frame, targets, lines):
    table = frame.copy()
    for j, axis in enumerate(ftdrake.WRENCH_AXES):
        table[f"meas_{axis}"] = targets[:, j]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ftdrake.train(table, kind="hybrid", robot="ftdrake", preset="none",
                             read=ReadOptions(velocities="qd_*", accelerations="qdd_*"),
                             progress=lines.append)


def test_a_hybrid_reports_its_residual_s_held_out_gain_over_physics(physics_targets):
    frame, rigid, cable = physics_targets
    lines = []
    result = _trained_on(frame, cable, lines)
    gain = result.provenance["residual_gain"]
    model, data = result.model, result.data
    # The physics part's error, independently: its predictions on the training rows.
    physics_error = data.Y - model.physics_.predict(data.X)
    np.testing.assert_allclose(gain["physics_rms"], np.sqrt(np.mean(physics_error ** 2, 0)),
                               rtol=1e-12)
    # The hybrid's error on rows its residual was not fitted on: the residual refitted on
    # alternate tenths of the rows and scored on the others.
    half = (np.arange(len(data.X)) * 10) // len(data.X) % 2 == 0
    error = np.empty_like(physics_error)
    for train in (half, ~half):
        part = clone(model.residual)  # the registry's default residual forest
        part.fit(data.X[train], physics_error[train])
        error[~train] = physics_error[~train] - part.predict(data.X[~train])
    np.testing.assert_allclose(gain["hybrid_rms"], np.sqrt(np.mean(error ** 2, 0)), rtol=1e-9)
    assert gain["gain"][0] > 0.3 and not gain["physics_alone_as_good"]  # the cable on Fx
    said = [line for line in lines if line.startswith("the residual's held-out gain")]
    assert len(said) == 1 and "meas_Fx" in said[0] and "physics alone" not in said[0]
    # Targets the payload model explains: the residual learns noise, and training says so.
    lines.clear()
    found = _trained_on(frame, rigid, lines).provenance["residual_gain"]
    assert max(found["gain"]) <= 0.05 and found["physics_alone_as_good"]
    assert any("physics alone is as good" in line and "kind physics" in line
               for line in lines)


def test_a_search_stopped_by_its_time_budget_says_so_and_what_it_chose():
    """Issue 42 item 12: the quick search with a spent budget scores one candidate, says it
    stopped early, how far it got and which option raises the bound; the provenance keeps it."""
    lines = []
    result = ftdrake.train(UR3_ID1, kind="rf", read=TORQUES, search_budget_s=0,
                           progress=lines.append)
    said = "\n".join(lines)
    assert ("the search stopped early: 1 of 4 candidates scored in " in said
            and "the next would have passed the time budget of 0 s (search_budget_s); the "
            "best of those 1 was chosen" in said), said
    tuning = result.provenance["tuning"]
    assert tuning["scored"] == [1] and tuning["time_budget_s"] == 0.0
    assert tuning["best_params"] == [tuning["candidates"][0]["params"][0]]
    with pytest.raises(ConfigError, match="search_budget_s: must be a non-negative"):
        ftdrake.train(UR3_ID1, kind="rf", read=TORQUES, search_budget_s=-1.0)
