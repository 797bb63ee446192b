"""The tests' own layout: each folder of tests/ mirrors a package of ftdrake (tests/datasets/ is
ftdrake.data's, tests/project/ the repository's), each is a package (so pytest names a test
module by its path and two folders may not collide), a test file's name is unique, and no test
module imports another test module: what tests share lives in tests/helpers.py, tests/conftest.py
or ftdrake.testing."""

import ast
from collections import Counter

from tests.helpers import ROOT

TESTS = ROOT / "tests"
#: Test folders that are not named like the package they test.
NOT_A_PACKAGE = {"project": None, "datasets": "data"}
SKIP = {"data", "__pycache__"}  # tests/data: the test data files


def folders():
    found = []
    for path in TESTS.rglob("*"):
        parts = path.relative_to(TESTS).parts
        if path.is_dir() and not SKIP & set(parts) and not parts[0].startswith("."):
            found.append(path)
    return found


def python_files():
    return [p for p in TESTS.rglob("*.py") if not SKIP & set(p.relative_to(TESTS).parts)]


def imported_modules(path):
    """Every module name an import statement of `path` names, relative ones with their dots
    (``from . import x`` gives ``.x``)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = "." * node.level + (node.module or "")
            names.append(base)
            names += [f"{base}.{alias.name}".replace("..", ".") for alias in node.names]
    return names


def is_test_module(name):
    return any(part.startswith("test_") or part == "conftest" for part in name.split("."))


def test_no_test_module_imports_another_test_module():
    offenders = {str(p.relative_to(ROOT)): bad for p in python_files()
                 if (bad := [m for m in imported_modules(p) if is_test_module(m)])}
    assert not offenders, (f"{offenders}: move what is shared to tests/helpers.py (or a fixture "
                           "to tests/conftest.py) and import it from there")


def test_each_folder_mirrors_a_package_of_ftdrake_and_is_a_package():
    for folder in folders():
        parts = list(folder.relative_to(TESTS).parts)
        if parts[0] in NOT_A_PACKAGE:
            if NOT_A_PACKAGE[parts[0]] is None:
                assert len(parts) == 1, f"{folder}: tests/{parts[0]}/ has no sub-folders"
                parts = None
            else:
                parts[0] = NOT_A_PACKAGE[parts[0]]
        if parts is not None:
            package = ROOT / "ftdrake" / "/".join(parts)
            assert (package / "__init__.py").is_file(), (
                f"{folder.relative_to(ROOT)} mirrors no package of ftdrake "
                f"(ftdrake/{'/'.join(parts)}/ is none): name it like the package its tests test")
        assert (folder / "__init__.py").is_file(), f"{folder.relative_to(ROOT)} lacks __init__.py"


def test_test_file_names_are_unique():
    names = Counter(p.name for p in python_files() if p.name.startswith("test_"))
    assert not [n for n, c in names.items() if c > 1], names.most_common(3)


def test_the_checks_see_the_tests():
    """The walk finds the test folders and modules the other checks judge (not an empty set)."""
    modules = python_files()
    assert {"runtime", "hardware", "project", "datasets"} <= {f.name for f in folders()}
    assert TESTS / "runtime" / "test_chain.py" in modules and len(modules) > 100
    assert is_test_module("tests.runtime.test_chain") and is_test_module(".test_chain")
    assert not is_test_module("tests.helpers") and not is_test_module("ftdrake.testing")
