"""examples/ur3_torque_models.py: the Python API reproduces ``ftdrake train`` + ``ftdrake
evaluate`` on the UR3 logs.

The expected table is what ``ftdrake train --targets 'tau_*' --velocities 'qd_*' …`` and
``ftdrake evaluate --json`` gave for the same four models on the same files (rf with
``--preset none``; arm and hybrid with ``--robot models/ur3.urdf --drive-gains identify``).
"""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "ur3_torque_models.py"
EXPECTED = """\
| model | tau_0 | tau_1 | tau_2 | tau_3 | tau_4 | tau_5 | 95 % coverage |
| --- | --- | --- | --- | --- | --- | --- | --- |
| rf | 0.903 | 0.294 | -0.589 | 0.635 | 0.852 | 0.856 | 0.39–0.73 |
| arm | 0.951 | 0.976 | 0.965 | 0.943 | 0.934 | 0.899 | 0.53–0.79 |
| hybrid (residual on q) | 0.952 | 0.969 | 0.960 | 0.941 | 0.936 | 0.890 | 0.55–0.75 |
| hybrid (residual on q,qd,qdd) | 0.951 | 0.972 | 0.963 | 0.940 | 0.935 | 0.906 | 0.57–0.76 |"""


@pytest.mark.slow
def test_example_reproduces_the_commands_table(tmp_path):
    result = subprocess.run([sys.executable, str(EXAMPLE), "--out", str(tmp_path / "out")],
                            cwd=tmp_path, capture_output=True, text=True, timeout=600,
                            check=False)
    assert result.returncode == 0, result.stderr
    assert "750 rows, 95.1 % outside the training range" in result.stdout
    assert result.stdout.rstrip().endswith(EXPECTED)
    assert (tmp_path / "out" / "arm_1.ftd").is_file()
    assert (tmp_path / "out" / "hybrid_3.json").is_file()
