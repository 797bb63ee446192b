"""Field checks shared by the config sections: each raises ConfigError naming the field."""

import math

from ..errors import ConfigError


def positive(v, name):
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
        raise ConfigError(f"{name}: must be a positive number, got {v!r}")


def non_negative(v, name):
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
        raise ConfigError(f"{name}: must be a non-negative number, got {v!r}")


def vector(values, n, name):
    if values is not None and not isinstance(values, (list, tuple)):
        raise ConfigError(f"{name}: must be a list of {n} numbers, got {values!r}")
    if values is None or len(values) != n:
        got = 0 if values is None else len(values)
        raise ConfigError(f"{name}: must have {n} entries, got {got}")
    finite(values, name)


def finite(values, name):
    if not isinstance(values, (list, tuple)):
        raise ConfigError(f"{name}: must be a list of numbers, got {values!r}")
    for v in values:
        if not (isinstance(v, (int, float)) and math.isfinite(v)):
            raise ConfigError(f"{name}: entries must be finite numbers, got {v!r}")


def six(values, name):
    vector(values, 6, name)
