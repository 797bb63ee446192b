"""The wheel a user installs: it carries the models, package.xml and the shipped scenario, and
the command runs from it in another folder.

The wheel is built offline (``pip wheel --no-build-isolation --no-index``) from a copy of the
files it is made of, so the checkout gets no build/ or *.egg-info; it needs setuptools >= 77
in this environment (``pip install -e '.[test]'`` brings it). "Installing" it means unpacking
it: a pure-Python wheel's contents are its installed layout.
"""

from __future__ import annotations

import importlib.metadata
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from tests.helpers import ROOT

BUILD_INPUTS = ("pyproject.toml", "README.md", "MANIFEST.in", "LICENSE", "ftdrake", "models")
MODEL_PATTERNS = ("package.xml", "*.sdf", "*.urdf", "*.dmd.yaml", "*.obj", "*.mtl")


def _setuptools_version() -> tuple[int, ...]:
    return tuple(int(p) for p in importlib.metadata.version("setuptools").split(".")[:2])


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    if _setuptools_version() < (77,):
        pytest.fail("building the wheel offline needs setuptools >= 77 here: "
                    "pip install -e '.[test]'")
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    junk = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", "build")
    for name in BUILD_INPUTS:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=junk)
        elif path.is_file():
            shutil.copy2(path, src / name)
    done = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "--no-build-isolation",
         "--no-index", "--quiet", "-w", str(tmp / "dist")],
        check=False, capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    (built,) = (tmp / "dist").glob("ftdrake-*.whl")
    return built


def _expected_model_files() -> set[str]:
    return {f"ftdrake/models/{p.name}" for pattern in MODEL_PATTERNS
            for p in (ROOT / "models").glob(pattern)}


def test_wheel_carries_models_package_xml_scenario_and_every_module(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    models = _expected_model_files()
    assert "ftdrake/models/package.xml" in models
    assert {"ftdrake/models/sda10d_arm.sdf", "ftdrake/models/ft_sensor_tool.sdf",
            "ftdrake/models/environment.sdf"} <= models
    assert models <= names, f"missing from the wheel: {sorted(models - names)}"
    assert "ftdrake/scenarios/default.yaml" in names
    # Every module of the source tree: a subpackage missing from pyproject's `packages` list
    # would be silently left out.
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / "ftdrake").rglob("*.py")}
    assert modules <= names, (f"not in the wheel (add the package to [tool.setuptools] "
                              f"packages in pyproject.toml): {sorted(modules - names)}")
    # Models live inside the package only; nothing else is installed at the top level.
    top = {n.split("/")[0] for n in names} - {"ftdrake"}
    assert len(top) == 1 and top.pop().endswith(".dist-info"), sorted(names)
    entry_points = zipfile.ZipFile(wheel).read(
        next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode()
    assert "ftdrake = ftdrake.cli:main" in entry_points


@pytest.mark.slow
def test_installed_wheel_runs_in_another_folder(wheel, tmp_path):
    """`python -m ftdrake` from the unpacked wheel, run elsewhere: --help, then a short free-motion
    simulation, which parses the shipped models through package://ftdrake/ (about 20 s)."""
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site), "MPLBACKEND": "Agg"}

    def run(*argv):
        return subprocess.run([sys.executable, *argv], check=False, cwd=elsewhere, env=env,
                              capture_output=True, text=True, timeout=300)

    where = run("-c", "import ftdrake, ftdrake.assets as a; print(ftdrake.__file__); "
                      "print(a.models_dir())")
    assert where.returncode == 0, where.stderr
    module, models = (Path(line) for line in where.stdout.split())
    assert module.is_relative_to(site) and models == site / "ftdrake" / "models"

    shown = run("-m", "ftdrake", "--help")
    assert shown.returncode == 0, shown.stderr
    assert shown.stdout.startswith("usage: ftdrake") and "demo" in shown.stdout

    ran = run("-m", "ftdrake", "simulate", "--scenario", "free", "--duration", "0.5",
              "--out", "sim", "--quiet")
    assert ran.returncode == 0, ran.stderr
    assert {p.name for p in (elsewhere / "sim").iterdir()} == {"log.parquet", "summary.json",
                                                               "wrench.png"}
