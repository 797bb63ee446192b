"""Griffe extension: ftdrake's docstrings as mkdocstrings renders them.

The code's docstrings are numpydoc-ish plain text written for ``help()``; three of their forms
are not Markdown and are rewritten here, once per loaded package, before rendering:

* Sphinx roles (``:class:`~ftdrake.x.Y```, ``:func:`.logs.read_table```, ``:data:`NAMES```)
  become cross-references when they name a public ftdrake object (rendered in the API
  reference), inline code otherwise (a private helper, another library). A role that names
  no object at all is stale: it is reported as a warning, which fails the strict build.
* Titled blocks (``Input ports:``, ``Output ports:``, ``State:``, ``Args:``, ``Attributes:``,
  any ``Title:`` line followed by an indented block) become a bold title and a bullet list,
  one bullet per entry, ``name (size): text`` with the name as code.
* numpydoc sections (``Parameters`` over a line of dashes, entries ``name : text``) become a
  bold title and a bullet list as well, ending at the first paragraph that is not an entry
  (griffe's numpy parser would read such prose as more parameters). A documented parameter
  that the signature does not have is stale: a warning, which fails the strict build.
* A paragraph ending in ``::`` followed by an indented block (reStructuredText's literal
  block) becomes a fenced code block.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import griffe

ROLE = re.compile(r":(?:py:)?(class|func|meth|mod|attr|data|obj|exc|const):`([^`]+)`")
TITLE = re.compile(r"^([A-Z][^:]{0,80}?):\s*$")
DASHES = re.compile(r"^\s*-{3,}\s*$")
ENTRY = re.compile(r"^(\*{0,2}\w+(?:\s*,\s*\*{0,2}\w+)*)\s*(?::\s*(.*))?$")
PARAMETER_TITLES = ("Parameters", "Args", "Arguments", "Other Parameters")
ITEM = re.compile(r"^([A-Za-z_][\w.]*(?:\[[^\]]*\])?)(\s*\([^)]*\))?:\s+(.*)$")
LOGGER = griffe.logger


class FtdrakeDocstrings(griffe.Extension):
    """Rewrites every docstring of the ``ftdrake`` package as described in the module."""

    def on_package(self, *, pkg: griffe.Module, loader, **kwargs) -> None:  # noqa: ARG002
        if pkg.name != "ftdrake":
            return
        for name, path in facade_exports(pkg.filepath).items():
            if name not in pkg.members:  # ftdrake.replay → ftdrake.offline.replay.replay
                pkg.set_member(name, griffe.Alias(name, path, parent=pkg))
        for obj in _walk(pkg):
            if obj.docstring is not None:
                text = _roles(obj.docstring.value, obj, loader)
                obj.docstring.value = _blocks(text, obj)


def facade_exports(init_path) -> dict[str, str]:
    """{public name: the path of the object it is} for the names ``ftdrake/__init__.py`` gives
    lazily (PEP 562, its ``_EXPORTS`` mapping of name → module), which griffe's static view of
    the package does not see."""
    tree = ast.parse(Path(init_path).read_text(encoding="utf-8"))
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        if any(isinstance(t, ast.Name) and t.id == "_EXPORTS" for t in targets):
            return {name: f"ftdrake.{module}.{name}"
                    for name, module in ast.literal_eval(node.value).items()}
    return {}


def _walk(obj):
    yield obj
    for member in obj.members.values():
        if not member.is_alias and (member.is_module or member.is_class):
            yield from _walk(member)
        elif not member.is_alias:
            yield member


# -- roles --------------------------------------------------------------------------------------

def _roles(text: str, obj, loader) -> str:
    def replace(match):
        kind, target = match.group(1), re.sub(r"\s+", "", match.group(2))
        if "<" in target and target.endswith(">"):  # :role:`title <target>`
            title, target = target[:-1].split("<", 1)
            title = title.strip()
        else:
            title = None
        short = target.startswith("~")
        target = target.lstrip("~")
        path = _resolve(target, obj, loader, kind)
        shown = title or (target.rsplit(".", 1)[-1] if short else target.lstrip("."))
        if path is None:
            return f"`{shown}`"
        if path is _STALE:
            LOGGER.warning(f"{_where(obj)}: :{kind}:`{match.group(2)}` names no object "
                           "(a stale reference: fix the docstring)")
            return f"`{shown}`"
        if _is_public(path):
            return f"[`{shown}`][{path}]"
        return f"`{shown}`"

    return ROLE.sub(replace, text)


_STALE = object()


def _resolve(target: str, obj, loader, kind: str):
    """The canonical path of `target` as seen from `obj`; None for an object outside ftdrake
    (another library's); _STALE for an ftdrake name that does not exist."""
    collection = loader.modules_collection
    if target.startswith("."):
        module = obj if obj.is_module else obj.module
        base = module if module.is_init_module else module.parent
        dots = len(target) - len(target.lstrip("."))
        for _ in range(dots - 1):
            base = base.parent
        path = f"{base.path}.{target.lstrip('.')}"
    elif target.startswith("ftdrake.") or target == "ftdrake":
        path = target
    else:
        head, _, rest = target.partition(".")
        path = _in_scope(head, obj)
        if path is None:
            found = _names(collection).get(head, [])
            if len(found) > 1:  # several objects of that name: shown, not linked
                return None
            if not found:
                return _STALE if kind in ("class", "func", "meth", "mod", "data", "exc") else None
            path = found[0]
        if rest:
            path = f"{path}.{rest}"
    if not path.startswith("ftdrake"):
        return None
    try:
        found = collection.get_member(path) if hasattr(collection, "get_member") else \
            collection[path]
    except (KeyError, ValueError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return _STALE
    try:
        return found.final_target.path if found.is_alias else found.path
    except (griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None


def _in_scope(name: str, obj) -> str | None:
    """`name` as Python would find it from `obj`: its class's members (inherited ones too),
    then the module's names (imports included). Elsewhere (``_names``) an unqualified name
    is looked up in the whole package, as Sphinx does: one object of that name is linked,
    several are shown as code."""
    scope = obj if (obj.is_module or obj.is_class) else obj.parent
    while scope is not None:
        if scope.is_class and name in scope.all_members:
            return f"{scope.path}.{name}"
        if scope.is_module:
            try:
                return scope.resolve(name)
            except griffe.NameResolutionError:
                return None
        scope = scope.parent
    return None


_INDEX: dict = {}


def _names(collection) -> dict:
    key = id(collection)
    if key not in _INDEX:
        index: dict = {}
        for module in collection.members.values():
            if module.name == "ftdrake":
                for obj in _walk(module):
                    index.setdefault(obj.name, []).append(obj.path)
        _INDEX[key] = index
    return _INDEX[key]


def _is_public(path: str) -> bool:
    """Whether the API reference renders `path`: no private part; a package's own members are
    not rendered on its page (they are on their defining module's)."""
    return not any(part.startswith("_") for part in path.split("."))


def _where(obj) -> str:
    return f"{obj.filepath}:{obj.lineno}" if obj.lineno else obj.path


# -- titled blocks and literal blocks ------------------------------------------------------------

def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _blocks(text: str, obj) -> str:
    lines = text.splitlines()
    out: list[str] = []
    i = 0
    fence = False
    while i < len(lines):
        line = lines[i]
        if line.lstrip().startswith("```"):
            fence = not fence
        if fence:
            out.append(line)
            i += 1
            continue
        if i + 1 < len(lines) and DASHES.match(lines[i + 1]) and line.strip():
            end = _numpy_section_end(lines, i + 2)
            title = line.strip()
            entries = _items(lines[i + 2:end], numpy=True)
            if title in PARAMETER_TITLES:
                _check_parameters(entries, obj)
            out.extend(["", f"**{title}**", "", *_bullets(entries), ""])
            i = end
            continue
        block_end = _indented_block_end(lines, i + 1, _indent(line))
        if line.rstrip().endswith("::") and block_end > i + 1:
            # A literal block: "text::" then an indented block (after an optional blank line).
            head = line.rstrip()[:-1].rstrip()
            if head.strip():
                out.append(head if head.endswith(":") else head + ":")
            body = [ln for ln in lines[i + 1:block_end]]
            out.extend(["", "```text", *_dedent(body), "```", ""])
            i = block_end
            continue
        match = TITLE.match(line.strip())
        if (match and not line.rstrip().endswith("::") and block_end > i + 1
                and _indent(lines[i + 1]) > _indent(line)):
            entries = _items(lines[i + 1:block_end])
            if match.group(1) in PARAMETER_TITLES:
                _check_parameters(entries, obj)
            out.extend(["", f"**{match.group(1)}**", "", *_bullets(entries), ""])
            i = block_end
            continue
        inline = re.match(r"^(Input ports|Output ports|State):\s+(\S.*)$", line.strip())
        if inline:
            out.extend(["", f"**{inline.group(1)}**: {inline.group(2)}"])
            i += 1
            continue
        out.append(line)
        i += 1
    return "\n".join(out)


def _indented_block_end(lines, start: int, base: int) -> int:
    """The index after the block of lines indented more than `base` from `start` (blank lines
    inside it included, trailing blank lines not)."""
    end = start
    j = start
    while j < len(lines) and (not lines[j].strip() or _indent(lines[j]) > base):
        if lines[j].strip():
            end = j + 1
        j += 1
    return end


def _dedent(body: list[str]) -> list[str]:
    width = min((_indent(ln) for ln in body if ln.strip()), default=0)
    return [ln[width:] for ln in body]


def _numpy_section_end(lines, start: int) -> int:
    """The index after a numpydoc section's entries: the first line at indentation 0 that is
    not an entry (after a blank line), or another section's title."""
    j = start
    while j < len(lines):
        line = lines[j]
        if j + 1 < len(lines) and DASHES.match(lines[j + 1]) and line.strip():
            return j
        if line.strip() and _indent(line) == 0 and not ENTRY.match(line.strip()):
            return j
        # After a blank line, a line continues the list only if it reads as an entry.
        if (line.strip() and _indent(line) == 0 and j > start and not lines[j - 1].strip()
                and " : " not in line and not line.strip().isidentifier()):
            return j
        j += 1
    return j


def _items(body: list[str], numpy: bool = False) -> list[tuple[str | None, str, str]]:
    """(name, size, text) per entry at the block's first indentation (deeper lines continue
    it); name None for an entry that names nothing."""
    body = _dedent(body)
    raw: list[str] = []
    for ln in body:
        if not ln.strip():
            continue
        if _indent(ln) == 0 or not raw:
            raw.append(ln.strip())
        else:
            raw[-1] += " " + ln.strip()
    entries = []
    for entry in raw:
        if numpy:
            match = re.match(r"^(\*{0,2}\w+(?:\s*,\s*\*{0,2}\w+)*)(?:\s+:\s*(.*)|\s+(.*))?$", entry)
            if match:
                entries.append((match.group(1), "", (match.group(2) or match.group(3) or "")))
                continue
        match = ITEM.match(entry)
        if match and match.group(3):
            entries.append((match.group(1), match.group(2) or "", match.group(3)))
        else:
            entries.append((None, "", entry))
    return entries


def _bullets(entries) -> list[str]:
    return [f"- `{name}`{size}: {text}" if name else f"- {text}" for name, size, text in entries]


def _check_parameters(entries, obj) -> None:
    """Warns for a documented parameter the signature of `obj` (a class: its __init__) lacks."""
    function = obj
    if obj.is_class:
        function = obj.members.get("__init__")
    if function is None or not getattr(function, "is_function", False):
        return
    names = {p.name for p in function.parameters}
    if any(p.kind and p.kind.value == "variadic keyword" for p in function.parameters):
        return
    for name, _, _ in entries:
        for part in (name or "").split(","):
            part = part.strip().lstrip("*")
            if part and part not in names:
                LOGGER.warning(f"{_where(obj)}: documents a parameter '{part}' that "
                               f"{function.path} does not take (a stale docstring)")
