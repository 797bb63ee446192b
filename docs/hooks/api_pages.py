"""MkDocs hook: the API reference and the code layout, generated from the source tree.

Every module of the ``ftdrake`` package gets rendered by mkdocstrings on its package's page
(``api/<package>.md``): a page per package, the package's docstring first, then each module.
``api/index.md`` lists the public names of ``ftdrake/__init__.py`` (``__all__``) with a link to
where each is defined, and ``guide/layout.md``'s marker expands to the module tree with each
module's first docstring line. Nothing here names a module by hand: a module added, moved or
removed changes the pages on the next build.
"""

from __future__ import annotations

import ast
import logging
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "ftdrake"
LAYOUT_MARKER = "<!-- ftdrake-code-layout -->"
LOG = logging.getLogger("mkdocs.plugins.ftdrake.api_pages")


def modules() -> dict[str, list[str]]:
    """{package dotted name: [its modules' dotted names]}, packages in tree order; in a
    package, the modules of its public names first (in its ``__all__``'s order: the
    ``ftdrake.runtime`` page opens with ``CompensationChain``), then the others by name;
    private modules (a leading underscore) and ``__main__`` left out."""
    packages: dict[str, list[str]] = {}
    for init in sorted(PACKAGE.rglob("__init__.py")):
        folder = init.parent
        rel = folder.relative_to(ROOT)
        if any(part.startswith(("_", ".")) for part in rel.parts):
            continue
        name = ".".join(rel.parts)
        stems = [p.stem for p in sorted(folder.glob("*.py")) if not p.stem.startswith("_")]
        first = [m for m in _public_modules(init) if m in stems]
        packages[name] = [f"{name}.{m}" for m in [*first, *(m for m in stems if m not in first)]]
    return packages


def _public_modules(init: Path) -> list[str]:
    """The modules (stems) of a package that define the names of its ``__all__``, in that
    order (each once), from its ``from .module import Name`` lines."""
    tree = ast.parse(init.read_text(encoding="utf-8"))
    source = {alias.asname or alias.name: node.module for node in tree.body
              if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module
              for alias in node.names}
    exported = next((ast.literal_eval(node.value) for node in tree.body
                     if isinstance(node, ast.Assign)
                     and any(getattr(t, "id", None) == "__all__" for t in node.targets)), [])
    return list(dict.fromkeys(source[n].split(".")[0] for n in exported if n in source))


def module_path(dotted: str) -> Path:
    path = ROOT.joinpath(*dotted.split("."))
    return path / "__init__.py" if path.is_dir() else path.with_suffix(".py")


def first_line(dotted: str) -> str:
    doc = ast.get_docstring(ast.parse(module_path(dotted).read_text(encoding="utf-8"))) or ""
    return doc.strip().splitlines()[0] if doc.strip() else ""


def page_uri(package: str) -> str:
    return f"api/{package}.md"


def package_page(package: str, members: list[str]) -> str:
    lines = [f"# `{package}`", "", f"::: {package}", "    options:", "      members: false",
             "      show_root_heading: false", ""]
    if members:
        lines += ["Modules: " + " · ".join(f"[`{m.rsplit('.', 1)[-1]}`][{m}]" for m in members),
                  ""]
    for module in members:
        lines += [f"::: {module}", ""]
    return "\n".join(lines)


def public_names() -> list[tuple[str, str]]:
    """(name, defining module path) for every name in ftdrake/__init__.py's ``__all__``,
    followed through the subpackages' re-exports with griffe."""
    import griffe  # noqa: PLC0415 (the docs extra's; this file runs only in a docs build)

    pkg = griffe.load("ftdrake", search_paths=[str(ROOT)], resolve_aliases=True,
                      resolve_external=False)
    lazy = _lazy_exports()
    names = []
    for name in pkg.exports or []:
        name = str(name)
        if name.startswith("__"):
            continue
        if name in lazy:  # given by the facade's __getattr__ (PEP 562): not a member for griffe
            member = pkg.get_member(lazy[name])
        else:
            member = pkg.get_member(name) if name in pkg.members else None
        if member is None:
            continue
        target = member.final_target if member.is_alias else member
        names.append((name, target.path, _summary(target)))
    return names


def _lazy_exports() -> dict[str, str]:
    """{name: path below ``ftdrake``} of the facade's ``_EXPORTS`` (name → module)."""
    for node in ast.parse((PACKAGE / "__init__.py").read_text(encoding="utf-8")).body:
        if (isinstance(node, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == "_EXPORTS" for t in node.targets)):
            return {name: f"{module}.{name}"
                    for name, module in ast.literal_eval(node.value).items()}
    return {}


def _summary(obj) -> str:
    doc = obj.docstring.value.strip() if obj.docstring else ""
    line = doc.splitlines()[0] if doc else ""
    return line.replace("|", "\\|")


def index_page(packages: dict[str, list[str]]) -> str:
    intro = ("Generated from the docstrings at every build. `import ftdrake` gives the names "
             "below; everything else lives in the packages listed after them. Each Drake "
             "system's page shows its ports as a block diagram drawn from a live instance.")
    lines = ["# API reference", "", intro,
             "", "## `import ftdrake`", "", "| name | defined in | what it is |",
             "| --- | --- | --- |"]
    for name, path, summary in public_names():
        module = path.rsplit(".", 1)[0]
        lines.append(f"| [`{name}`][{path}] | `{module}` | {summary} |")
    lines += ["", "## Packages", "", "| package | modules | what it holds |", "| --- | --- | --- |"]
    for package, members in packages.items():
        lines.append(f"| [`{package}`]({package}.md) | {len(members)} | {first_line(package)} |")
    return "\n".join(lines) + "\n"


def layout_markdown(packages: dict[str, list[str]]) -> str:
    lines = []
    for package, members in packages.items():
        lines.append(f"- [`{package}`](../api/{package}.md): {first_line(package)}")
        for module in members:
            lines.append(f"    - [`{module.rsplit('.', 1)[-1]}`][{module}]: {first_line(module)}")
    return "\n".join(lines) + "\n"


# -- mkdocs events -----------------------------------------------------------------------------

def on_config(config):
    """Puts the generated package pages under the nav's "API reference" entry."""
    packages = modules()
    entries = [{"Overview": "api/index.md"}] + [{package: page_uri(package)}
                                                for package in packages]
    for i, item in enumerate(config.nav or []):
        if isinstance(item, dict) and "API reference" in item:
            config.nav[i] = {"API reference": entries}
            return config
    LOG.warning("mkdocs.yml: the nav has no 'API reference' entry for the generated pages")
    return config


def on_files(files, config):
    packages = modules()
    files.append(File.generated(config, "api/index.md", content=index_page(packages)))
    for package, members in packages.items():
        files.append(File.generated(config, page_uri(package),
                                    content=package_page(package, members)))
    return files


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001
    if LAYOUT_MARKER in markdown:
        markdown = markdown.replace(LAYOUT_MARKER, layout_markdown(modules()))
    return markdown
