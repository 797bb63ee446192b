"""`ftdrake export`: a saved model → ONNX whose output equals the model's predict."""

import numpy as np
import onnxruntime as ort

from ftdrake import RandomForestCompensator, save_model
from ftdrake import conventions as col
from ftdrake.cli.main import main


def test_export_cli_matches_predict(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (300, 21))
    Y = np.column_stack([np.sin(X[:, j]) for j in range(6)])
    model = RandomForestCompensator(features="q", n_estimators=8, random_state=0).fit(X, Y)
    path = save_model(model, tmp_path / "m.ftd", target_names=col.WRENCH_AXES,
                      target_units=col.WRENCH_UNITS)
    assert main(["export", "--model", str(path), "--out", str(tmp_path / "m.onnx")]) == 0
    session = ort.InferenceSession(str(tmp_path / "m.onnx"))
    Xq = rng.uniform(-1.2, 1.2, (50, 21))
    got = session.run(None, {session.get_inputs()[0].name: Xq})[0]
    np.testing.assert_allclose(got, model.predict(Xq), rtol=0, atol=1e-9)


def test_export_cli_refuses_corrupt_model(tmp_path, capsys):
    bad = tmp_path / "bad.ftd"
    bad.write_bytes(b"FTDRAKE-MODEL\nnot json\n")
    assert main(["export", "--model", str(bad), "--out", str(tmp_path / "m.onnx")]) == 2
    assert "bad.ftd" in capsys.readouterr().err
    assert not (tmp_path / "m.onnx").exists()
