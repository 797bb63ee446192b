"""The package's layers as built: no module imports one from a layer above its own.

Bottom-up (``ftdrake/__init__.py`` documents them): base → physics → data → compensation →
runtime / offline → systems → sim / hardware → experiments → cli, and the ``ftdrake`` facade on
top, which no module inside the package imports. Within the sim / hardware layer, ``hardware``
(the live robot) imports nothing of ``sim`` or ``systems``; ``sim`` may use the hardware's
wire modules (messages, transport, config) to publish a simulated robot.

Inside ``compensation`` the same holds for its parts (``compensation/__init__.py`` documents
them): features → contract / compiled / identification / evaluation → estimators → calibration /
files, a part importing only parts of a lower layer (not even one of its own layer), so no import
goes up and none goes round in a circle.

Checked statically on every import statement (inside functions too) of every module, since
importing any ``ftdrake.*`` runs the facade, which imports everything; and at run time for
the two live-robot layers, with the facade replaced by a bare package so that only what they
import themselves is loaded.
"""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ftdrake"

# Top-level module or package of ftdrake → layer (higher may import lower and its own).
LAYERS = {
    **dict.fromkeys(("conventions", "errors", "config", "signals", "io", "assets", "version",
                     "parallel"), 0),  # parallel: the Dask backend collection and tuning share
    "physics": 1,
    "control": 1,  # ILC's filter and update law: array math like physics'
    "data": 2,
    "compensation": 3,
    "runtime": 4,
    # The recorder every station and replay use (offline/recorder.py); runtime/replay.py
    # records with it. Offline tools above the runtime, below sim and hardware (which record).
    "offline": 4,
    "systems": 5,
    "sim": 6,
    "hardware": 6,
    "experiments": 7,
    "plots": 7,  # the figures experiments and the command line write
    "testing": 7,  # generators for the tests and benchmarks
    "cli": 8,
    "__main__": 8,
    "": 9,  # the facade, ftdrake/__init__.py
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


# With the facade replaced by a bare package, import the layer and list what got loaded.
_LOADED = """
import importlib, sys, types
facade = types.ModuleType("ftdrake")
facade.__path__ = [sys.argv[1]]
sys.modules["ftdrake"] = facade
importlib.import_module(sys.argv[2])
print("\\n".join(name for name in sys.modules if name.startswith("ftdrake.")))
"""


@pytest.mark.parametrize("layer, never", [
    ("ftdrake.hardware", ("sim", "systems")),
    ("ftdrake.runtime", ("sim", "systems", "hardware", "experiments", "cli")),
])
def test_the_live_layers_load_no_simulation(layer, never):
    path = os.pathsep.join([str(PACKAGE.parent), *filter(None, [os.environ.get("PYTHONPATH")])])
    done = subprocess.run([sys.executable, "-c", _LOADED, str(PACKAGE), layer],
                          capture_output=True, text=True, timeout=120, check=False,
                          env={**os.environ, "PYTHONPATH": path})
    assert done.returncode == 0, done.stderr
    loaded = done.stdout.split()
    assert layer in loaded
    assert not [m for m in loaded if part(m) in never], loaded
