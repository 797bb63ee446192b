"""examples/ur3_torque_models.py: the Python API reproduces ``ftdrake train`` + ``ftdrake
evaluate`` on the UR3 logs.

The expected table is what ``ftdrake train --targets 'tau_*' --velocities 'qd_*' …`` and
``ftdrake evaluate --json`` gave for the same four models on the same files (rf with
``--preset none``; arm and hybrid with ``--robot models/ur3.urdf --drive-gains identify``).
"""

import subprocess
import sys

import numpy as np
import pytest

from tests.helpers import ROOT

EXAMPLE = ROOT / "examples" / "ur3_torque_models.py"
EXPECTED = """\
| model | tau_0 | tau_1 | tau_2 | tau_3 | tau_4 | tau_5 | 95 % coverage |
| --- | --- | --- | --- | --- | --- | --- | --- |
| rf | 0.903 | 0.294 | -0.589 | 0.635 | 0.852 | 0.856 | 0.39–0.73 |
| arm | 0.951 | 0.976 | 0.965 | 0.943 | 0.934 | 0.899 | 0.53–0.79 |
| hybrid (default, on q,qd,qdd) | 0.952 | 0.976 | 0.965 | 0.943 | 0.934 | 0.891 | 0.49–0.74 |
| hybrid (residual on q) | 0.952 | 0.976 | 0.966 | 0.943 | 0.934 | 0.890 | 0.48–0.76 |"""


def table_numbers(lines) -> dict:
    """{model: [variance score per joint..., coverage low, coverage high]} of a table."""
    rows = {}
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        low, high = cells[-1].split("–")
        rows[cells[0]] = [float(c) for c in cells[1:-1]] + [float(low), float(high)]
    return rows


@pytest.mark.slow
def test_example_reproduces_the_commands_table(tmp_path):
    result = subprocess.run([sys.executable, str(EXAMPLE), "--out", str(tmp_path / "out")],
                            cwd=tmp_path, capture_output=True, text=True, timeout=600,
                            check=False)
    assert result.returncode == 0, result.stderr
    assert "750 rows, 95.1 % outside the training range" in result.stdout
    # Two runs of the same code on the same files differed by up to 0.009 in a variance score
    # (the hybrid with a residual on q, tau_5: 0.890 and 0.881): the arm's SDP solve and the
    # forest are not bit-reproducible across machines' thread schedules. The table is compared
    # number by number to 0.015.
    got = table_numbers(result.stdout.rstrip().splitlines()[-len(EXPECTED.splitlines()):])
    want = table_numbers(EXPECTED.splitlines())
    assert got.keys() == want.keys()
    for model, numbers in want.items():
        np.testing.assert_allclose(got[model], numbers, rtol=0, atol=0.015, err_msg=model)
    assert (tmp_path / "out" / "arm_1.ftd").is_file()
    assert (tmp_path / "out" / "hybrid_3.json").is_file()
