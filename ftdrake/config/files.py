"""Scenario files: YAML in (validated, naming the bad field) and out."""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
import typing
import warnings
from importlib import resources
from pathlib import Path

import yaml as pyyaml

from ..errors import ConfigError
from ..io import atomic_write_text
from .chain import ChainConfig
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
    data = _mapping(text, source)
    moved = schema is ScenarioConfig and _moved_chain_sections(data, source)
    if _check_fields(data, schema, _where(schema)) or moved:
        text = pyyaml.safe_dump(data, sort_keys=False)  # moved sections, widened scalars
    try:
        from pydrake.common.yaml import yaml_load_typed  # noqa: PLC0415 (see _DRAKE_ON_USE)

        config = yaml_load_typed(schema=schema, data=text)
    except (RuntimeError, ValueError, TypeError) as e:
        raise ConfigError(f"{source}: {e}") from None
    return config.validate()


#: The transport sections a live config file has beside ``chain:``
#: (:class:`~ftdrake.hardware.live_config.LiveConfig`).
LIVE_TRANSPORTS = ("lcm", "ros2")


def load_chain_config(path: "str | Path | None" = None) -> ChainConfig:
    """The :class:`ChainConfig` of a file: a chain config (``compensator``, ``bias_tracker``,
    ``detector``, ``sensor``, ``robot`` at the top), a live config file's ``chain:``
    section, or, until the next release, a scenario
    file's chain (``scenario.chain_config()``: its chain section on its simulated sensor's
    stream), with a :class:`ConfigLayoutWarning` naming the chain layout. None: defaults."""
    if path is None:
        return ChainConfig().validate()
    path = Path(path)
    text = _read(path)
    data = _mapping(text, str(path))
    chain_fields = {f.name for f in dc.fields(ChainConfig)}
    if set(data) <= chain_fields:
        return parse_config(text, ChainConfig, source=str(path))
    if "chain" in data and set(data) <= {"chain", *LIVE_TRANSPORTS}:  # a live config file
        return parse_config(pyyaml.safe_dump(data["chain"] or {}), ChainConfig,
                            source=f"{path}: chain")
    warnings.warn(
        f"{path}: a scenario file where a chain config is expected; its chain section on the "
        "simulated sensor's stream is used until the next release. A chain config holds "
        f"only {', '.join(sorted(chain_fields))} at its top (a scenario's 'chain:' section, "
        "with sensor: {rate_hz: ..., noise_std: [...]} the live sensor's).",
        ConfigLayoutWarning, stacklevel=2)
    return parse_config(text, ScenarioConfig, source=str(path)).chain_config()


def save_config(config, path: "str | Path") -> None:
    """Writes `config` as YAML, atomically."""
    atomic_write_text(Path(path), dump_config(config))


def dump_config(config) -> str:
    from pydrake.common.yaml import yaml_dump_typed  # noqa: PLC0415 (see _DRAKE_ON_USE)

    return yaml_dump_typed(config)


def read_mapping(path: Path) -> dict:
    """The top-level mapping of the YAML file `path` (errors name the file)."""
    return _mapping(_read(path), str(path))


def _read(path: Path) -> str:
    try:
        return path.read_text()
    except OSError as e:
        raise ConfigError(f"cannot read config {path}: {e.strerror}") from None


def _mapping(text: str, source: str) -> dict:
    """The YAML text's top-level mapping ({} for an empty file)."""
    try:
        data = pyyaml.safe_load(text)
    except pyyaml.YAMLError as e:
        raise ConfigError(f"{source}: malformed YAML: {e}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of fields, got {type(data).__name__}")
    return data


#: Scenario sections that moved under ``chain:`` (the product's own config).
CHAIN_SECTIONS = ("compensator", "detector", "bias_tracker")


class ConfigLayoutWarning(FutureWarning):
    """A config file in a layout that still loads but will not in the next release."""


def _moved_chain_sections(data: dict, source: str) -> bool:
    """Moves a scenario's top-level ``compensator``/``detector``/``bias_tracker`` (the layout
    before ``chain:``) under ``chain:``, with a warning naming the new layout. True when any
    moved."""
    moved = [key for key in CHAIN_SECTIONS if key in data]
    if not moved:
        return False
    chain = data.setdefault("chain", {}) or {}
    if not isinstance(chain, dict):
        raise ConfigError(f"{source}: scenario.chain: expected a mapping of sections")
    both = [key for key in moved if key in chain]
    if both:
        raise ConfigError(f"{source}: scenario.{both[0]} and scenario.chain.{both[0]} are both "
                          f"given; keep only scenario.chain.{both[0]}")
    for key in moved:
        chain[key] = data.pop(key)
    data["chain"] = chain
    warnings.warn(
        f"{source}: the scenario sections {', '.join(moved)} now live under 'chain:' "
        f"(scenario.chain.{moved[0]}: ...); this layout loads until the next release. Indent "
        "them under a 'chain:' key (ftdrake's shipped scenario shows the layout).",
        ConfigLayoutWarning, stacklevel=3)
    return True


def _where(schema) -> str:
    """The prefix an error names a field of `schema` with."""
    return {ScenarioConfig: "scenario", ChainConfig: "chain"}.get(schema, schema.__name__)


def _check_fields(data: dict, schema, where: str) -> bool:
    """Names unknown fields and mistyped values with their full path (Drake's loader names
    only the leaf, or nothing); widens a single number given for a per-axis list (a field of
    six entries, one per wrench axis) to that list, in place. Returns whether it widened any."""
    fields = {f.name: f for f in dc.fields(schema)}
    hints = typing.get_type_hints(schema)
    widened = False
    for key, value in data.items():
        if key not in fields:
            raise ConfigError(f"{where}.{key}: unknown field; known fields: {sorted(fields)}")
        field, hint = fields[key], hints.get(key)
        sub = field.default_factory if field.default_factory is not dc.MISSING else None
        if sub is not None and dc.is_dataclass(sub):
            if not isinstance(value, dict):
                raise ConfigError(f"{where}.{key}: must be a mapping of fields "
                                  f"({sorted(f.name for f in dc.fields(sub))}), got {value!r}")
            widened |= _check_fields(value, sub, f"{where}.{key}")
            continue
        widen = _check_value(value, hint, field, f"{where}.{key}")
        if widen is not None:
            data[key] = widen
            widened = True
    return widened


def _is_number(value) -> bool:
    """A number as Drake's loader reads one: an int or float, or text such as ``1.7e5`` (which
    YAML 1.1, and so PyYAML, leaves a string)."""
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return False
        return True
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _entries(field) -> "int | None":
    """How many entries a list field holds, when its definition says: `metadata["entries"]`,
    else the length of its default list."""
    if "entries" in field.metadata:
        return int(field.metadata["entries"])
    if field.default_factory is not dc.MISSING:
        default = field.default_factory()
        if isinstance(default, list) and default:
            return len(default)
    return None


#: What a value of each scalar type must be: (test, the words that say so).
_SCALARS = {
    float: (_is_number, "a number"),
    int: (lambda v: isinstance(v, int) and not isinstance(v, bool), "a whole number"),
    bool: (lambda v: isinstance(v, bool), "true or false"),
    str: (lambda v: isinstance(v, str), "a string"),
}


def _check_value(value, hint, field, name: str):
    """Raises ConfigError naming `name` when `value` does not fit the type `hint`; returns the
    widened list when a single number was given for a per-axis (six-entry) list, else None."""
    if typing.get_origin(hint) is typing.Union and type(None) in typing.get_args(hint):
        if value is None:
            return None
        hint = next(a for a in typing.get_args(hint) if a is not type(None))
    if hint in _SCALARS:
        ok, words = _SCALARS[hint]
        if not ok(value):
            raise ConfigError(f"{name}: must be {words}, got {value!r}")
    elif typing.get_origin(hint) is dict and not isinstance(value, dict):
        raise ConfigError(f"{name}: must be a mapping, got {value!r}")
    elif typing.get_origin(hint) is list:
        return _check_list(value, (typing.get_args(hint) or (None,))[0], _entries(field), name)
    return None


def _check_list(value, item, n: "int | None", name: str):
    """`_check_value` for a list of `item`s (`n` of them, when known)."""
    if item is float and _is_number(value):
        if n == 6:
            return [float(value)] * 6  # one value for every wrench axis
        count = f"{n} numbers" if n else "numbers"
        raise ConfigError(f"{name}: must be a list of {count}, got the single number {value!r}")
    if not isinstance(value, list):
        raise ConfigError(f"{name}: must be a list, got {value!r}")
    if item in _SCALARS:
        ok, words = _SCALARS[item]
        for v in value:
            if not ok(v):
                plural = words[2:] + "s" if words.startswith("a ") else words
                raise ConfigError(f"{name}: entries must be {plural}, got {v!r}")
    return None
