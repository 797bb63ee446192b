"""Shared fixtures: session-scoped simulated datasets (small: a few seconds per trajectory)
and the command line run in-process."""

import numpy as np
import pytest

from ftdrake import ScenarioConfig
from ftdrake.cli.main import main as cli_main
from ftdrake.sim.collection import collect


def _collect(trajectories, duration, kind="fourier", seed=0, **changes):
    config = ScenarioConfig()
    if changes.get("rigid"):
        config.cable.enabled = False
        config.sensor.crosstalk = 0.0
    return collect(config, trajectories, seed=seed, kind=kind, duration=duration, n_jobs=2,
                   progress=False)


@pytest.fixture(scope="session")
def rigid_dataset():
    """Free motion, no cable, no cross-talk; sensor noise, bias and drift on."""
    return _collect(3, 10.0, rigid=True)


@pytest.fixture(scope="session")
def realistic_dataset():
    """Free motion with the default scenario: cable and cross-talk on."""
    return _collect(4, 10.0, seed=10)


@pytest.fixture
def rng():
    return np.random.default_rng(0)


@pytest.fixture
def ftdrake(capsys):
    """Runs an `ftdrake` command in-process; returns (exit code, stdout, stderr)."""

    def run(*argv):
        code = cli_main([str(a) for a in argv])
        out, err = capsys.readouterr()
        return code, out, err

    return run
