"""`ftdrake export-correction`: a two-part model file and a joint path → the correction CSV."""

import numpy as np
import pandas as pd

from ftdrake.cli.main import main
from ftdrake.experiments.reference_correction import desired_states
from ftdrake.experiments.two_part_model import TwoPartModel, read_joint_path
from ftdrake.systems.learned_feedforward import fit_feedforward_gp
from ftdrake.testing import sine_path


def test_export_correction_writes_the_models_offsets_at_the_rate(tmp_path):
    X = sine_path(4.0, seed=0, rate_hz=100.0)
    q = X[:, :7]
    model = TwoPartModel(fit_feedforward_gp(X, 1e-4 * np.cos(q), max_points=50,
                                            optimize_points=100))
    file = model.save(tmp_path / "two_part.ftd")
    t = np.arange(0.0, 4.0, 0.01)
    path = tmp_path / "path.csv"
    pd.DataFrame({"time": t, **{f"q_{j}": q[:, j] for j in range(7)}}).to_csv(path,
                                                                                index=False)
    out = tmp_path / "correction.csv"
    assert main(["export-correction", "--model", str(file), "--path", str(path), "--rate",
                 "500", "--out", str(out)]) == 0
    table = pd.read_csv(out)
    np.testing.assert_allclose(np.diff(table["time"]), 2e-3, atol=1e-12)
    trajectory = read_joint_path(path, 7)
    times = table["time"].to_numpy()
    expected = (model.reference(trajectory).vector_values(times)
                - trajectory.vector_values(times)).T
    np.testing.assert_allclose(table[[f"offset_{j}" for j in range(7)]], expected, atol=1e-15)
    _, std, confidence = model.correction.evaluate(desired_states(trajectory, times))
    np.testing.assert_allclose(table[[f"offset_std_{j}" for j in range(7)]], confidence * std,
                               rtol=1e-12)


def test_export_correction_names_a_bad_model_file(tmp_path, capsys):
    bad = tmp_path / "bad.ftd"
    bad.write_bytes(b"not a model")
    path = tmp_path / "path.csv"
    path.write_text("time,q_0\n0,0\n")
    out = tmp_path / "c.csv"
    assert main(["export-correction", "--model", str(bad), "--path", str(path), "--out",
                 str(out)]) == 2
    assert "bad.ftd: not a two-part model file" in capsys.readouterr().err
    assert not out.exists()
