"""The type names of model files written before ``compensation/`` was split into sub-packages.

A model file names every type it holds by its module path (skops's schema, and the manifest's
``model_class``). Until ``compensation/`` was split into ``estimators/``, ``identification/``,
``calibration/``, ... those paths were ``ftdrake.compensation.<module>``; :data:`MOVED_MODULES`
says where each such module is now, and the loader (:mod:`.persistence`) reads a file's type
names through it (:func:`current_name`, :func:`current_payload`) before it checks them
against the trusted types and rebuilds the model. Nothing else is aliased: the old module
paths do not import.
"""

from __future__ import annotations

import io
import json
import zipfile

#: Old module path → where it is now, for every module whose types a model file may hold.
MOVED_MODULES = {f"ftdrake.compensation.{old}": f"ftdrake.compensation.{new}" for old, new in (
    ("forest", "estimators.forest"),
    ("svr", "estimators.svr"),
    ("gpr", "estimators.gpr"),
    ("physics", "estimators.physics"),
    ("hybrid", "estimators.hybrid"),
    ("arm", "estimators.arm"),
    ("tuning", "estimators.tuning"),  # PerOutputCompensator
    ("consistent", "identification.consistent"),  # a physics model's identification, prior
    ("orientation_model", "calibration.orientation_model"),
    ("domain_calibrated", "estimators.domain_calibrated"),  # DomainCalibratedHybrid
)}
_SCHEMA = "schema.json"  # the member of a skops archive that names the types


def current_name(name: str) -> str:
    """`name` (``module.Class``) with its module where it is now."""
    module, _, cls = name.rpartition(".")
    return f"{MOVED_MODULES[module]}.{cls}" if module in MOVED_MODULES else name


def current_payload(payload: bytes) -> bytes:
    """The skops payload `payload` with every moved module path in its schema replaced by the
    current one; `payload` itself when it names none (a file written after the split).

    An archive that cannot be read is returned unchanged, for the loader to refuse.
    """
    try:
        with zipfile.ZipFile(io.BytesIO(payload)) as archive:
            schema = json.loads(archive.read(_SCHEMA))
            if not _rename(schema):
                return payload
            out = io.BytesIO()
            with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as renamed:
                for info in archive.infolist():
                    data = (json.dumps(schema).encode() if info.filename == _SCHEMA
                            else archive.read(info))
                    renamed.writestr(info.filename, data)
    except (zipfile.BadZipFile, KeyError, ValueError, UnicodeDecodeError):
        return payload
    return out.getvalue()


def _rename(node) -> bool:
    """Replaces moved module paths in the ``__module__`` entries of a skops schema in place;
    whether any was replaced."""
    changed = False
    if isinstance(node, dict):
        module = node.get("__module__")
        if isinstance(module, str) and module in MOVED_MODULES:
            node["__module__"] = MOVED_MODULES[module]
            changed = True
        children = node.values()
    elif isinstance(node, list):
        children = node
    else:
        return False
    for child in children:
        changed = _rename(child) | changed
    return changed
