"""The user-facing example runs from a clean folder and does what it says."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "compensate_in_your_diagram.py"


def test_example_builds_own_diagram_and_compensates_at_rest(tmp_path):
    result = subprocess.run([sys.executable, str(EXAMPLE)], cwd=tmp_path, capture_output=True,
                            text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    numbers = re.search(r"near zero\): \[([^\]]*)\]", result.stdout).group(1)
    external = np.array([float(x) for x in numbers.split()])
    assert np.abs(external[:3]).max() < 0.2  # N: compensated to within the model's error
    assert "contact detected: False" in result.stdout
    assert (tmp_path / "out" / "example_model.ftd").is_file()
