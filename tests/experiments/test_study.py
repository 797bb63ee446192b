"""The study end to end on a tiny configuration, its outputs, findings and command line."""

from __future__ import annotations

import argparse
import json
import math

import pytest

from ftdrake import ScenarioConfig
from ftdrake.cli import study as cli
from ftdrake.experiments import study as dut
from ftdrake.experiments.study import Finding, describe
from ftdrake.sim.collection import collect
from ftdrake.version import result_provenance

# A grid of one candidate each (by registry name): the test checks the plumbing, not the tuning.
TINY_GRID = {
    "rf": [
        {"n_estimators": [8], "max_features": [1.0], "min_samples_leaf": [5]}],
    "svr": [{"kernel": ["rbf"], "C": [10.0], "gamma": [0.1]}],
}
TINY = {"preset": TINY_GRID, "trajectories": 3, "test_trajectories": 1, "duration": 4.0,
        "train_hz": 25.0, "test_hz": 50.0, "n_splits": 3, "n_jobs": 2, "progress": False}


@pytest.fixture(scope="module")
def tiny_data():
    """Three 4 s runs of each dataset's motion (collected once for the module)."""
    return {kind: collect(ScenarioConfig(), TINY["trajectories"], kind=kind,
                          duration=TINY["duration"], n_jobs=2, progress=False)
            for kind in dut.DATASETS}


@pytest.fixture(scope="module")
def tiny_run(tiny_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    return out, dut.run_study(out, data=tiny_data, **TINY)


@pytest.mark.slow
def test_results_hold_every_cell(tiny_run):
    out, returned = tiny_run
    results = json.loads((out / "results.json").read_text())
    assert results["findings"] == returned["findings"]
    assert results["provenance"] == result_provenance(results["provenance"]["command"])
    for dataset in dut.DATASETS:
        table = results["metrics"][dataset]
        assert set(table) == set(dut.METHODS)
        for method in dut.METHODS:
            assert set(table[method]) == set(dut.FEATURES)
            for features in dut.FEATURES:
                cell = table[method][features]
                assert list(cell) == list(dut.AXES)
                for axis in dut.AXES:
                    assert set(cell[axis]) == set(dut.METRICS)
                    values = cell[axis].values()
                    assert all(isinstance(v, float) and math.isfinite(v) for v in values), (
                        dataset, method, features, axis, cell[axis])
                timing = results["timings"][dataset][method][features]
                assert timing["fit_s"] >= 0 and timing["predict_s"] >= 0
        for method in ("rf", "svr"):
            for features in dut.FEATURES:
                assert set(results["best_params"][dataset][method][features]) == set(dut.AXES)


@pytest.mark.slow
def test_results_hold_the_study_tables(tiny_run):
    _, results = tiny_run
    for dataset in dut.DATASETS:
        sizes = results["sizes"][dataset]
        # Whole trajectories are held out: none is on both sides.
        assert sizes["test_trajectories"] == [2]
        assert sizes["train_trajectories"] == [0, 1]
        assert sizes["train_rows"] == 2 * 4.0 * 25.0  # 2 runs × 4 s × 25 Hz
        tip = results["tool_tip"][dataset]
        assert set(tip) == {"x", "y", "z", "tilt"}
        assert tip["z"]["min"] <= tip["z"]["mean"] <= tip["z"]["max"]
        fx = results["feature_importances"][dataset]
        assert len(fx["q,qd,qdd"]) == 21 and len(fx["q"]) == 7
        assert sum(fx["q"].values()) == pytest.approx(1.0)
        disagreement = results["cv_disagreement"][dataset]
        for scheme in ("grouped", "shuffled"):
            assert math.isfinite(disagreement[scheme]["median_test_over_cv"])
    assert results["grid_sizes"]["RandomForestCompensator"] == {"q": 1, "q,qd": 1,
                                                                "q,qd,qdd": 1}
    # The study-like motion moves the tool tip less in z than z_rich.
    assert (results["tool_tip"]["reference"]["z"]["std"]
            < results["tool_tip"]["z_rich"]["z"]["std"])


@pytest.mark.slow
def test_figures_and_markdown_are_written(tiny_run):
    out, _ = tiny_run
    for dataset in dut.DATASETS:
        for name in dut.FIGURES:
            png = out / f"{name}_{dataset}.png"
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "results.md").read_text()
    assert "## Findings" in text and "Grouped vs shuffled CV" in text
    assert not list(out.glob(".*")), "staging or temporary files left behind"


def _no_prose(value):
    """Numbers, booleans, and short labels (axis, feature set, input names) only."""
    if isinstance(value, dict):
        return all(_no_prose(k) and _no_prose(v) for k, v in value.items())
    if isinstance(value, list):
        return all(_no_prose(v) for v in value)
    return isinstance(value, (bool, int, float)) or (isinstance(value, str) and " " not in value)


@pytest.mark.slow
def test_findings_are_numbers_and_the_report_words_them(tiny_run):
    _, results = tiny_run
    found = dut.check_findings(results)
    assert [f.id for f in found] == ["a", "b", "c", "d", "e", "f"]
    for f in found:
        assert isinstance(f.reproduced, bool) and _no_prose(f.numbers), f
        json.dumps(f.as_dict())
    records = dut.finding_records(found)
    assert records == results["findings"]
    for record in records:
        assert record["claim"] and record["evidence"]
        if record["reproduced"]:
            assert record["why"] is None
        assert Finding.from_dict(record) in found


# -- prose chosen from the numbers -----------------------------------------------------------
AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def _c(worst_first, physics=0.01, tz_floor=0.003):
    nmse = dict(zip(worst_first, [0.9, 0.8, 0.5, 0.1, 0.05, 0.02], strict=True))
    return Finding("c", "study", "reference", False, {
        "mean_nmse": nmse, "worst_first": list(worst_first),
        "noise_floor_nmse": {a: (tz_floor if a == "Tz" else 0.3) for a in AXES},
        "physics_nmse": dict.fromkeys(AXES, physics)})


def test_claim_c_why_speaks_only_of_the_worst_axes():
    # As in the quick study: Fx and Fz worst; the physics model gets Fx right.
    _, why = describe(_c(("Fx", "Fz", "Ty", "Tz", "Tx", "Fy")))
    assert why.startswith("the worst axes here are Fx and Fz. Fz is hard for the study's")
    assert "but our Tz varies well above the noise" in why
    assert "while the black boxes interpolate Fx poorly" in why
    # Tz worst, Fz not: no "Fz is hard", no "Tz varies well above the noise".
    _, why = describe(_c(("Tz", "Fx", "Fz", "Ty", "Tx", "Fy")))
    assert "Fz is hard" not in why and "Tz varies" not in why
    assert "The black boxes interpolate Fx poorly" in why
    # The physics model no better than the black boxes: no claim that they interpolate poorly.
    _, why = describe(_c(("Fx", "Fz", "Ty", "Tz", "Tx", "Fy"), physics=5.0))
    assert "interpolate" not in why
    # Reproduced: no reason at all.
    found = _c(("Fz", "Tz", "Fx", "Ty", "Tx", "Fy"))
    assert describe(Finding("c", "study", "reference", True, found.numbers))[1] is None


def _d(nmse_q, nmse_full, rf_change):
    b = Finding("b", "study", "reference", False, {
        "largest_change": {"reference": {"rf": rf_change, "svr": -1.0}},
        "rf_unchanged": abs(rf_change) < 0.05, "svr_changed": True})
    d = Finding("d", "study", "reference", False, {
        "q_share": {"reference": 0.5, "z_rich": 0.6}, "threshold": 0.8,
        "top3": ["q_1", "qd_0", "q_0"], "top3_q_only": ["q_1", "q_0", "q_2"],
        "rf_fx_nmse": {"q": nmse_q, "q,qd,qdd": nmse_full}})
    return describe(d, {"b": b, "d": d})[1]


def test_claim_d_why_follows_whether_the_derivatives_help():
    assert "(see b), so the forest spends splits on them; they do not help" in _d(0.8, 0.9, -0.2)
    assert "(see b)" not in _d(0.8, 0.9, -0.01)  # b's explanation is not printed then
    helped = _d(0.9, 0.5, -0.2)
    assert "do not help" not in helped and "carry information about Fx" in helped


def test_claim_a_and_f_reasons_need_their_numbers():
    numbers = {"cells": 18, "rf_wins": {"reference": 0, "z_rich": 3},
               "rf_wins_vs_scaled_svr": {"reference": 0, "z_rich": 2},
               "svr_wins_reference": [], "shuffled_test_over_cv": 0.8, "svr_epsilon": 0.05,
               "narrow_axes_std": {"Tz": 0.02}}
    _, why = describe(Finding("a", "study", "reference", False, numbers))
    assert "shuffled CV" not in why and "Where RF does win" not in why
    f = {"reference": {"axes": 4, "median_ratio": 2.0}, "z_rich": {"axes": 6, "median_ratio": 3.0}}
    quiet = {**f, "excitation_warnings": {"reference": 0, "z_rich": 0}}
    warned = {**f, "excitation_warnings": {"reference": 1, "z_rich": 0}}
    assert describe(Finding("f", "ftdrake", "reference", False, quiet))[1] is None
    assert "see the warnings" in describe(Finding("f", "ftdrake", "reference", False, warned))[1]


@pytest.mark.slow
def test_a_failing_run_leaves_no_partial_output(tiny_data, tmp_path, monkeypatch):
    out = tmp_path / "study"
    out.mkdir()
    (out / "earlier.txt").write_text("kept")

    def broken(*args, **kwargs):
        raise RuntimeError("figure failed")

    monkeypatch.setitem(dut.FIGURE_MAKERS, "importances", broken)
    with pytest.raises(RuntimeError, match="figure failed"):
        dut.run_study(out, data=tiny_data, **TINY)
    assert sorted(p.name for p in out.iterdir()) == ["earlier.txt"]


def test_a_failure_before_writing_creates_nothing(tmp_path):
    out = tmp_path / "study"
    with pytest.raises(ValueError, match="test_trajectories"):
        dut.run_study(out, trajectories=2, test_trajectories=2, progress=False)
    assert not out.exists()


def test_only_keeps_the_feature_blocks():
    import numpy as np

    X = np.arange(2 * 21, dtype=float).reshape(2, 21) + 1
    Z = dut.only(X, "q,qd")
    assert np.array_equal(Z[:, :14], X[:, :14]) and not Z[:, 14:].any()


# -- command line ----------------------------------------------------------------------------
def _parser():
    parser = argparse.ArgumentParser(prog="ftdrake")
    cli.register(parser.add_subparsers(dest="command", required=True))
    return parser


def test_cli_defaults_are_the_quick_study():
    args = _parser().parse_args(["study"])
    assert args.preset == "quick" and args.cv == "grouped" and not args.quiet
    assert str(args.out) == "out/study"
    assert (args.trajectories, args.duration) == (dut.TRAJECTORIES, dut.DURATION_S)
    assert args.run is cli.run_command


def test_cli_parses_every_option():
    args = _parser().parse_args(["study", "--paper", "--out", "x", "--trajectories", "4",
                                 "--duration", "8", "--cv", "shuffled", "--seed", "3",
                                 "--train-hz", "50", "--quiet"])
    assert (args.preset, str(args.out), args.trajectories, args.duration, args.cv, args.seed,
            args.train_hz, args.quiet) == ("paper", "x", 4, 8.0, "shuffled", 3, 50.0, True)
    with pytest.raises(SystemExit):
        _parser().parse_args(["study", "--quick", "--paper"])


def test_cli_prints_estimate_then_findings(monkeypatch, capsys):
    calls = {}
    finding = {"id": "a", "claim": "RF beats SVR", "reproduced": False, "evidence": "3/18"}

    def fake_run_study(out_dir, **kwargs):
        calls.update(kwargs, out_dir=out_dir)
        return {"wall_time_s": 1.0, "findings": [finding]}

    monkeypatch.setattr(dut, "run_study", fake_run_study)
    args = _parser().parse_args(["study", "--quick", "--quiet", "--out", "o"])
    assert args.run(args) == 0
    printed = capsys.readouterr().out
    first = printed.splitlines()[0]
    assert "preset quick" in first and "estimated time" in first
    assert "wrote o/results.json" in printed and "RF beats SVR" in printed
    assert calls["preset"] == "quick" and calls["progress"] is False


def test_cli_paper_runs_the_study_protocol_on_a_cluster(monkeypatch, capsys):
    from ftdrake.experiments.study import paper

    calls = {}

    def fake_run_paper(out_dir, **kwargs):
        calls.update(kwargs, out_dir=out_dir)
        return {"wall_time_s": 2.0, "findings": {"study": {"a": {"reproduced": False}}}}

    monkeypatch.setattr(paper, "run_paper", fake_run_paper)
    args = _parser().parse_args(["study", "--paper", "--quiet", "--out", "o",
                                 "--cluster", "tcp://h:8786"])
    assert args.run(args) == 0
    first = capsys.readouterr().out.splitlines()[0]
    # The exhaustive count: 720 RF candidates on q × 5 folds × 6 axes.
    assert "rf q 21600" in first and "halving" in first and "tcp://h:8786" in first
    assert calls["scheduler"] == "tcp://h:8786" and calls["features"] == ("q",)
    assert calls["search"] == "halving"


def test_paper_estimate_dwarfs_quick():
    quick, paper = dut.estimate_seconds("quick"), dut.estimate_seconds("paper")
    assert 60 < quick < 600
    assert paper > 100 * quick
