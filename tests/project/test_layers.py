"""The package's layers as built: no module imports one from a layer above its own, no
circle, and the live stations load nothing of the simulation.

Bottom-up (``ftdrake/__init__.py`` documents them): base → physics → data → compensation →
runtime → offline → systems → sim / hardware → experiments → cli, and the ``ftdrake`` facade
on top, which no module inside the package imports. ``offline`` (the recorder, replay,
thresholds, the residual budget) records and replays the runtime chain: the live stations
use it, it uses nothing of the simulation. Within the sim / hardware layer, ``hardware``
(the live robot) imports nothing of ``sim`` or ``systems``; ``sim`` may use the hardware's
wire modules (messages, transport, config) to publish a simulated robot.

Inside ``compensation`` the same holds for its parts (``compensation/__init__.py`` documents
them): features → contract / compiled / identification / evaluation → estimators → calibration /
files, a part importing only parts of a lower layer (not even one of its own layer), so no import
goes up and none goes round in a circle.

Checked statically on every import statement (inside functions too) of every module, and at
run time, in a fresh interpreter: what importing a live station or an offline tool loads,
through the lazy facade as a user imports it and with the facade replaced by a bare package.
"""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import ROOT

PACKAGE = ROOT / "ftdrake"

# Top-level module or package of ftdrake → layer (higher may import lower and its own).
LAYERS = {
    **dict.fromkeys(("conventions", "errors", "config", "signals", "io", "assets", "version",
                     "parallel"), 0),  # parallel: the Dask backend collection and tuning share
    "physics": 1,
    "control": 1,  # ILC's filter and update law: array math like physics'
    "data": 2,
    "compensation": 3,
    "runtime": 4,
    "training": 4,  # ftdrake.train: the training pipeline on compensation and data
    # Tools around the runtime: the recorder every station, simulate and replay use, replay,
    # thresholds, the residual budget. Above the runtime, below sim and hardware (which record).
    "offline": 5,
    "systems": 6,
    "sim": 7,
    "hardware": 7,
    "experiments": 8,
    "plots": 8,  # the figures experiments and the command line write
    "testing": 8,  # generators for the tests and benchmarks
    "cli": 9,
    "__main__": 9,
    "": 10,  # the facade, ftdrake/__init__.py
}
# Imports between the parts of one layer that are not allowed: (importer, imported) → the
# imported part's modules it may import anyway.
FORBIDDEN_IN_LAYER = {
    ("hardware", "sim"): (),
    ("sim", "hardware"): ("ftdrake.hardware.messages", "ftdrake.hardware.transport",
                          "ftdrake.hardware.config", "ftdrake.hardware.ros2.messages",
                          "ftdrake.hardware.ros2.dds", "ftdrake.hardware.ros2.config"),
}
FORBIDDEN_BELOW = {"hardware": ("systems",)}  # the live robot runs no simulation rig

# The parts of compensation (a module at its top or a sub-package) → layer; a part imports only
# parts of a lower layer.
COMPENSATION_LAYERS = {
    "": 0,  # the package itself (a docstring)
    "features": 0,  # the input layout every compensator takes
    **dict.fromkeys(("contract", "compiled", "identification", "evaluation"), 1),
    "estimators": 2,
    **dict.fromkeys(("calibration", "files"), 3),
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def part(module: str) -> str:
    """The top-level part of the package a module belongs to ("" for the facade)."""
    return module.split(".")[1] if "." in module else ""


def imported_modules(module: str, path: Path):
    """(line, module) for every ftdrake module `module`'s import statements name; a name
    imported from a package is that package's submodule when there is one, else the package."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "ftdrake":
                    yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
                if source.split(".")[0] != "ftdrake":
                    continue
            for alias in node.names:
                submodule = f"{source}.{alias.name}"
                yield node.lineno, submodule if submodule in MODULES else source


def compensation_part(module: str) -> str | None:
    """The part of compensation a module belongs to ("" for the package), None outside it."""
    parts = module.split(".")
    if parts[1:2] != ["compensation"]:
        return None
    return parts[2] if len(parts) > 2 else ""


def violation(importer: str, imported: str) -> str | None:
    """Why `importer` may not import `imported`, or None."""
    a, b = part(importer), part(imported)
    if a == b == "compensation":
        return compensation_violation(importer, imported)
    if a == b:
        return None
    if LAYERS[b] > LAYERS[a]:
        return f"{b or 'the ftdrake facade'} (layer {LAYERS[b]}) is above {a} ({LAYERS[a]})"
    if LAYERS[b] == LAYERS[a] and (a, b) in FORBIDDEN_IN_LAYER:
        allowed = FORBIDDEN_IN_LAYER[(a, b)]
        if imported not in allowed:
            return (f"{a} may not import {b}" + (f" (only {', '.join(allowed)})" if allowed
                                                 else ""))
    if b in FORBIDDEN_BELOW.get(a, ()):
        return f"{a} may not import {b}"
    return None


def compensation_violation(importer: str, imported: str) -> str | None:
    """Why `importer` may not import `imported`, both in compensation, or None."""
    a, b = compensation_part(importer), compensation_part(imported)
    if a == b:
        return None
    la, lb = COMPENSATION_LAYERS[a], COMPENSATION_LAYERS[b]
    if lb > la:
        return f"compensation.{b} (layer {lb}) is above compensation.{a} ({la})"
    if lb == la:
        return f"compensation.{b} is in the layer of compensation.{a} ({la})"
    return None


def test_every_part_of_the_package_has_a_layer():
    parts = {part(m) for m in MODULES}
    assert parts <= set(LAYERS), f"give {sorted(parts - set(LAYERS))} a layer in LAYERS"


def test_every_part_of_compensation_has_a_layer():
    parts = {compensation_part(m) for m in MODULES} - {None}
    assert parts <= set(COMPENSATION_LAYERS), (
        f"give {sorted(parts - set(COMPENSATION_LAYERS))} a layer in COMPENSATION_LAYERS")


def test_no_module_imports_from_a_layer_above_it():
    found = []
    for module, path in MODULES.items():
        for line, imported in imported_modules(module, path):
            why = violation(module, imported)
            if why:
                found.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {module} imports "
                             f"{imported}: {why}")
    assert not found, "\n".join(found)


@pytest.mark.parametrize("importer, imported, expected", [
    ("ftdrake.runtime.chain", "ftdrake.systems.sensor_gravity", "above"),
    ("ftdrake.runtime.chain", "ftdrake.sim.station", "above"),
    ("ftdrake.runtime.chain", "ftdrake.hardware.messages", "above"),
    ("ftdrake.hardware.station", "ftdrake.sim.scene", "may not import sim"),
    ("ftdrake.hardware.station", "ftdrake.systems.ft_sensor", "may not import systems"),
    ("ftdrake.hardware.station", "ftdrake", "facade"),
    ("ftdrake.sim.lcm_publisher", "ftdrake.hardware.station", "only"),
    ("ftdrake.sim.lcm_publisher", "ftdrake.hardware.messages", None),
    ("ftdrake.compensation.estimators.physics", "ftdrake.data.logs", None),
    ("ftdrake.data.logs", "ftdrake.compensation.estimators.physics", "above"),
    ("ftdrake.cli.main", "ftdrake.experiments.demo", None),
    ("ftdrake.runtime.chain", "ftdrake.offline.replay", "above"),
    ("ftdrake.offline.replay", "ftdrake.systems.ft_sensor", "above"),
    ("ftdrake.offline.replay", "ftdrake.sim.simulate", "above"),
    ("ftdrake.offline.residual_budget", "ftdrake.experiments.demo", "above"),
    ("ftdrake.offline.replay", "ftdrake.runtime.chain", None),
    ("ftdrake.hardware.station", "ftdrake.offline.replay", None),
    ("ftdrake.compensation.estimators.physics", "ftdrake.compensation.identification.consistent",
     None),
    ("ftdrake.compensation.identification.consistent", "ftdrake.compensation.estimators.physics",
     "above"),
    ("ftdrake.compensation.evaluation.metrics", "ftdrake.compensation.estimators.base", "above"),
    ("ftdrake.compensation.evaluation.metrics", "ftdrake.compensation.identification.inertial",
     "in the layer"),
    ("ftdrake.compensation.estimators.hybrid", "ftdrake.compensation.evaluation.metrics", None),
    ("ftdrake.compensation.files.persistence", "ftdrake.compensation.calibration.static_table",
     "in the layer"),
    ("ftdrake.compensation.compiled.rows", "ftdrake.compensation.features", None),
    ("ftdrake.compensation.features", "ftdrake.compensation.compiled.rows", "above"),
    ("ftdrake.compensation.estimators.base", "ftdrake.compensation.estimators.forest", None),
])
def test_the_rules_themselves(importer, imported, expected):
    why = violation(importer, imported)
    assert (why is None) if expected is None else (expected in why), why


def test_compensations_modules_import_one_another_in_no_circle():
    """Modules that import none of the others left, or that none of them imports, are dropped
    until none is; what is left imports round in circles."""
    graph = {m: {i for _, i in imported_modules(m, p) if i in MODULES and i != m}
             for m, p in MODULES.items() if compensation_part(m) is not None}
    graph = {m: deps & graph.keys() for m, deps in graph.items()}
    while True:
        imported = set().union(*graph.values())
        ends = {m for m, deps in graph.items() if not deps or m not in imported}
        if not ends:
            break
        graph = {m: deps - ends for m, deps in graph.items() if m not in ends}
    assert not graph, f"modules importing round in a circle: {sorted(graph)}"


def test_relative_imports_resolve_to_modules():
    path = PACKAGE / "hardware" / "core.py"
    imported = {m for _, m in imported_modules("ftdrake.hardware.core", path)}
    assert {"ftdrake.runtime.chain", "ftdrake.hardware.messages", "ftdrake.config"} <= imported
    assert all(m in MODULES for m in imported), imported - set(MODULES)


def reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    """Every node a path of one or more arrows leads to from `start` (itself only on a
    circle)."""
    found, todo = set(), list(graph[start])
    while todo:
        node = todo.pop()
        if node not in found:
            found.add(node)
            todo.extend(graph[node])
    return found


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The circles of `graph` (module → the modules it imports): the groups of modules each of
    which reaches every other (strongly connected components of more than one node)."""
    reach = {node: reachable(graph, node) for node in graph}
    found, placed = [], set()
    for node in sorted(graph):
        group = sorted(other for other in reach[node] if node in reach[other])
        if group and node not in placed:
            found.append(group)
            placed.update(group)
    return found


def packages_of(module: str) -> set[str]:
    """The packages whose ``__init__`` importing `module` runs (``ftdrake.a`` for
    ``ftdrake.a.b``), the facade left out."""
    parts = module.split(".")
    return {".".join(parts[:k]) for k in range(2, len(parts))}


def import_graph() -> dict[str, set[str]]:
    """Module → the modules importing it runs: those it names and the packages they are in
    (but its own packages, which are running already when it runs)."""
    graph = {}
    for module, path in MODULES.items():
        named = {m for _, m in imported_modules(module, path) if m in MODULES}
        runs = named | {p for m in named for p in packages_of(m)}
        graph[module] = runs - packages_of(module) - {module} - {"ftdrake"}
    return graph


def test_no_circle_of_imports():
    found = circles(import_graph())
    assert not found, found


def test_circles_finds_a_circle_and_only_one():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert circles(graph) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


# Import a module in a fresh interpreter and list the ftdrake modules that got loaded; with
# "bare", the facade is first replaced by a bare package (only what the module imports loads).
_LOADED = """
import importlib, sys, types
if sys.argv[3] == "bare":
    facade = types.ModuleType("ftdrake")
    facade.__path__ = [sys.argv[1]]
    sys.modules["ftdrake"] = facade
importlib.import_module(sys.argv[2])
print("\\n".join(name for name in sys.modules if name.split(".")[0] == "ftdrake"))
"""


def loaded_by(module: str, facade: str = "lazy") -> list[str]:
    """The ftdrake modules a fresh interpreter holds after ``import module`` (this tree's)."""
    path = os.pathsep.join([str(PACKAGE.parent), *filter(None, [os.environ.get("PYTHONPATH")])])
    done = subprocess.run([sys.executable, "-c", _LOADED, str(PACKAGE), module, facade],
                          capture_output=True, text=True, timeout=120, check=False,
                          env={**os.environ, "PYTHONPATH": path})
    assert done.returncode == 0, done.stderr
    loaded = done.stdout.split()
    assert module in loaded
    return loaded


@pytest.mark.parametrize("layer, never", [
    ("ftdrake.hardware", ("sim", "systems")),
    ("ftdrake.runtime", ("offline", "sim", "systems", "hardware", "experiments", "cli")),
    ("ftdrake.offline.replay", ("sim", "systems", "hardware", "experiments", "cli")),
    ("ftdrake.offline.thresholds", ("sim", "systems", "hardware", "experiments", "cli")),
    ("ftdrake.offline.residual_budget", ("sim", "systems", "hardware", "experiments", "cli")),
])
def test_the_live_layers_load_no_simulation(layer, never):
    loaded = loaded_by(layer, facade="bare")
    assert not [m for m in loaded if part(m) in never], loaded


@pytest.mark.parametrize("station", ["ftdrake.hardware.station", "ftdrake.hardware.ros2.station"])
def test_a_live_station_imported_as_a_user_does_loads_no_simulation(station):
    """Through the real facade: ``import ftdrake.hardware.station`` runs ``ftdrake/__init__``,
    which must load nothing on its own."""
    loaded = loaded_by(station)
    assert not [m for m in loaded if part(m) in ("sim", "systems", "experiments", "cli")], loaded


def test_the_facade_still_gives_every_public_name():
    """Each name of ``__all__`` resolves (its module loaded on first use) to the object its
    module defines; a submodule is reached as an attribute; an unknown name is refused."""
    code = ("import importlib, ftdrake; from ftdrake import _EXPORTS; "
            "assert set(_EXPORTS) | {'__version__'} == set(ftdrake.__all__); "
            "assert set(ftdrake.__all__) <= set(dir(ftdrake)); "
            "bad = [n for n, m in _EXPORTS.items() if getattr(ftdrake, n) is not "
            "getattr(importlib.import_module('ftdrake.' + m), n)]; assert not bad, bad; "
            "assert ftdrake.sim.simulate.simulate is ftdrake.simulate; "
            "assert not hasattr(ftdrake, 'no_such_name')")
    path = os.pathsep.join([str(PACKAGE.parent), *filter(None, [os.environ.get("PYTHONPATH")])])
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, check=False, env={**os.environ, "PYTHONPATH": path})
    assert done.returncode == 0, done.stderr
