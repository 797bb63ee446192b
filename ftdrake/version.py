"""The installed ftdrake's version (the lowest layer: anything may import it)."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version


def ftdrake_version() -> str:
    """The installed distribution's version, or ``"0.0.0+unknown"`` in an uninstalled tree."""
    try:
        return version("ftdrake")
    except PackageNotFoundError:
        return "0.0.0+unknown"
