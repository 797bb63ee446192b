"""Scenario files: YAML in (validated, naming the bad field) and out."""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
from importlib import resources
from pathlib import Path

import yaml as pyyaml

from ..errors import ConfigError
from ..io import atomic_write_text
from .scenario import ScenarioConfig

# _DRAKE_ON_USE: Drake's YAML reader and writer are imported where a file is read or written,
# so that importing the configuration (the command line's flags and help) loads no pydrake.

# ----------------------------------------------------------------------------------------------
# YAML in and out.
# ----------------------------------------------------------------------------------------------
def default_scenario_path() -> Path:
    """The scenario file shipped with ftdrake (the defaults, written out)."""
    return Path(str(resources.files("ftdrake") / "scenarios" / "default.yaml"))


def load_config(path: "str | Path | None" = None, schema=ScenarioConfig):
    """Reads a YAML file into `schema` and validates it. None → the shipped default."""
    path = Path(path) if path is not None else default_scenario_path()
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(f"cannot read config {path}: {e.strerror}") from None
    return parse_config(text, schema, source=str(path))


def parse_config(text: str, schema=ScenarioConfig, source: str = "<string>"):
    """Parses YAML text into `schema`, naming the bad field on error."""
    try:
        data = pyyaml.safe_load(text)
    except pyyaml.YAMLError as e:
        raise ConfigError(f"{source}: malformed YAML: {e}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of fields, got {type(data).__name__}")
    _check_fields(data, schema, "scenario" if schema is ScenarioConfig else schema.__name__)
    try:
        from pydrake.common.yaml import yaml_load_typed  # noqa: PLC0415 (see _DRAKE_ON_USE)

        config = yaml_load_typed(schema=schema, data=text)
    except (RuntimeError, ValueError, TypeError) as e:
        raise ConfigError(f"{source}: {e}") from None
    if hasattr(config, "validate"):
        config.validate()
    return config


def save_config(config, path: "str | Path") -> None:
    """Writes `config` as YAML, atomically."""
    atomic_write_text(Path(path), dump_config(config))


def dump_config(config) -> str:
    from pydrake.common.yaml import yaml_dump_typed  # noqa: PLC0415 (see _DRAKE_ON_USE)

    return yaml_dump_typed(config)


def _check_fields(data: dict, schema, where: str) -> None:
    """Names unknown fields with their full path (Drake's loader names only the leaf)."""
    fields = {f.name: f for f in dc.fields(schema)}
    for key, value in data.items():
        if key not in fields:
            raise ConfigError(f"{where}.{key}: unknown field; known fields: {sorted(fields)}")
        sub = fields[key].default_factory if fields[key].default_factory is not dc.MISSING else None
        if sub is not None and dc.is_dataclass(sub) and isinstance(value, dict):
            _check_fields(value, sub, f"{where}.{key}")

