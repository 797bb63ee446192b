"""Where ftdrake's shipped files are: the models (SDF, model directives, package.xml).

In a source checkout the models live in the top-level ``models/`` folder; an installed wheel
carries the same files inside the package as ``ftdrake/models`` (see pyproject.toml). Both
resolve ``package://ftdrake/...`` offline through ``models/package.xml``: nothing is fetched at
run time.
"""

from __future__ import annotations

from pathlib import Path

from pydrake.multibody.parsing import Parser


def models_dir() -> Path:
    """The folder holding ftdrake's model files and their package.xml."""
    here = Path(__file__).resolve().parent
    candidates = (here / "models", here.parent / "models")  # wheel, then source checkout
    for candidate in candidates:
        if (candidate / "package.xml").is_file():
            return candidate
    raise FileNotFoundError(
        "ftdrake's models (with package.xml) are in neither "
        f"{' nor '.join(str(c) for c in candidates)}: the installation is incomplete; "
        "reinstall ftdrake (pip install ftdrake, or pip install . in a checkout)"
    )


def offline_parser(plant, package_xmls=()) -> Parser:
    """A Parser for `plant` that resolves ``package://ftdrake/`` to the shipped models and the
    packages of `package_xmls`; FileNotFoundError names a package.xml that does not exist."""
    parser = Parser(plant)
    parser.package_map().AddPackageXml(str(models_dir() / "package.xml"))
    for xml in package_xmls:
        if not Path(xml).is_file():
            raise FileNotFoundError(f"no such package.xml {xml!r}")
        parser.package_map().AddPackageXml(xml)
    return parser
