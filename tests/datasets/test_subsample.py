"""train --max-rows: a subsample that covers the log's states, reported in the model."""

import numpy as np
import pytest

from ftdrake.data.subsample import covering_rows


def brute_force_farthest(points, k):
    chosen = [0]
    for _ in range(k - 1):
        d = np.min([((points - points[c]) ** 2).sum(axis=1) for c in chosen], axis=0)
        chosen.append(int(np.argmax(d)))
    return chosen


def test_covering_rows_is_farthest_point_on_every_k_th_row_in_scaled_inputs():
    rng = np.random.default_rng(0)
    X = np.c_[rng.normal(size=(1000, 2)) * [1.0, 100.0], rng.normal(size=(1000, 1))]
    dut = covering_rows(X, 50, columns=2)
    candidates = np.arange(0, 1000, 10)  # every ceil(1000 / (2·50)) = 10th row
    used = X[candidates, :2]
    scaled = (used - used.mean(axis=0)) / used.std(axis=0)
    expected = np.sort(candidates[brute_force_farthest(scaled, 50)])
    np.testing.assert_array_equal(dut, expected)
    assert np.all(np.diff(dut) > 0)  # time order
    # The extremes of each used input are kept.
    for c in range(2):
        assert candidates[np.argmax(used[:, c])] in dut
        assert candidates[np.argmin(used[:, c])] in dut


def test_covering_rows_keeps_recordings_apart_and_short_logs_whole():
    X = np.arange(40, dtype=float)[:, None]
    np.testing.assert_array_equal(covering_rows(X, 100), np.arange(40))
    groups = np.repeat([7, 3], 20)  # in file order: 7 first
    dut = covering_rows(X, 10, groups=groups)
    assert len(dut) == 10 and set(np.arange(0, 40, 2)) >= set(dut)
    with pytest.raises(ValueError, match="max_rows"):
        covering_rows(X, 0)


@pytest.mark.slow
def test_train_max_rows_fits_on_the_cover_and_says_so(tmp_path, capsys):
    import ftdrake
    from ftdrake.cli.main import main as train_cli
    from ftdrake.compensation.files.persistence import read_manifest

    runs = {}
    for seed in (1, 2):
        scenario = ftdrake.ScenarioConfig()
        scenario.trajectory.kind, scenario.trajectory.duration_s = "fourier", 10.0
        scenario.trajectory.seed = scenario.sensor.seed = seed
        runs[seed] = ftdrake.simulate(ftdrake.build_station(scenario.validate()),
                                      progress=False).log
        ftdrake.save_dataset(runs[seed], tmp_path / f"run{seed}.parquet")
    errors = {}
    for name, extra in (("full", []), ("cover", ["--max-rows", "1000"])):
        out = tmp_path / f"{name}.ftd"
        assert train_cli(["train", "--data", str(tmp_path / "run1.parquet"), "--model",
                          "physics", "--robot", "ftdrake", "--out", str(out), *extra]) == 0
        model = ftdrake.load_model(out)
        held_out = runs[2]
        residual = (ftdrake.wrench_targets(held_out)
                    - model.predict(ftdrake.joint_state_layout(held_out)))
        errors[name] = np.sqrt(np.mean(residual ** 2, axis=0))
        manifest = read_manifest(out)["extra"]
    err = capsys.readouterr().err
    assert "chose 1000 rows" in err and "fitted in" in err
    assert manifest["subsample"]["rows_in"] == 10_000
    assert manifest["subsample"]["rows_used"] == manifest["rows"]["used"] == 1000
    # Within 5 % of the full fit on held-out motion (forces, N).
    np.testing.assert_array_less(errors["cover"][:3], 1.05 * errors["full"][:3])
