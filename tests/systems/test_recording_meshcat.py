"""The Meshcat a replay file is recorded with prints no "listening at http://…" line (its
server ends with the process: the address would lead nowhere), and it is the only Meshcat
ftdrake's commands, the demo and the docs build start."""

import ast
import logging

from pydrake.geometry import Meshcat, MeshcatParams, Rgba, Sphere

from ftdrake.systems.wrench_arrows import recording_meshcat
from tests.helpers import ROOT


def test_recording_meshcat_says_nothing_and_records(caplog):
    params = MeshcatParams()
    params.host, params.port = "localhost", 0
    with caplog.at_level(logging.INFO, logger="drake"):
        Meshcat(params)  # Drake's own: the line this test would catch
    assert "Meshcat listening for connections" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="drake"):
        meshcat = recording_meshcat()
    assert "listening" not in caplog.text
    assert logging.getLogger("drake").level == logging.INFO  # left as it was
    meshcat.SetObject("ball", Sphere(0.1), Rgba(1, 0, 0, 1))
    assert "<html" in meshcat.StaticHtml().lower()


def test_nothing_else_starts_a_meshcat():
    """No module of ftdrake and no docs hook constructs a Meshcat but recording_meshcat."""
    found = []
    for path in [*(ROOT / "ftdrake").rglob("*.py"), *(ROOT / "docs" / "hooks").glob("*.py")]:
        tree = ast.parse(path.read_text())
        for func in ast.walk(tree):
            if not isinstance(func, ast.FunctionDef):
                continue
            for node in ast.walk(func):
                if (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Meshcat"
                        and func.name != "recording_meshcat"):
                    found.append(f"{path.relative_to(ROOT)}: {func.name}")
    assert not found, found
