"""What a training run is asked to do: :class:`TrainOptions`, the one spelling of every option.

`ftdrake.train`, the ``ftdrake train`` command and any other reader take this object; a field's
name is the option's name everywhere (the command's flag is the name with dashes, ``max_rows``
↔ ``--max-rows``; ``delay_s`` ↔ ``--delay``). Messages about an option name it through
:func:`spelled_option` (:func:`~ftdrake.errors.option_name`), which a front end (the command
line) spells its own way (:func:`~ftdrake.errors.option_names`).
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..compensation.estimators import registry
from ..compensation.estimators.domain import IN_DOMAIN_SOURCES
from ..compensation.features import FEATURE_SETS
from ..data.training import ReadOptions
from ..errors import ConfigError, option_name

#: The default bound on the ``quick`` search's time (s, wall clock): on an idle machine the
#: search of a few thousand rows takes a fraction of it; on a busy one it stops there and
#: chooses among the candidates scored.
SEARCH_BUDGET_S = 600.0

#: The presets of :attr:`TrainOptions.preset`: ``quick`` tunes the kinds that have a grid
#: (grouped CV), ``none`` fits the kind's own parameters.
PRESETS = ("quick", "none")

def spelled_option(name: str) -> str:
    """How messages name option `name` (a :class:`TrainOptions` field, or ``read.FIELD`` for
    a :class:`~ftdrake.data.training.ReadOptions` one): the name itself in Python, the flag on
    the command line (:func:`~ftdrake.errors.option_name`)."""
    return option_name(name)


@dc.dataclass(frozen=True)
class TrainOptions:
    """How :func:`ftdrake.train` fits a compensator on a log.

    kind: a compensator registry name (``rf``, ``svr``, ``gpr``, ``physics``, ``hybrid``,
      ``arm``, ...); None: ``hybrid`` with a `robot` and wrench targets, else ``rf``.
    features: the model's inputs, ``q``, ``q,qd`` or ``q,qd,qdd``; None: the kind's default.
    preset: ``quick`` (grid search with grouped 5-fold CV, for the kinds that have a grid;
      the others fit their parameters from data) or ``none`` (the kind's own parameters).
    robot, sensor_frame, base_frame, joints, fixed_joints: the robot description a
      robot-based kind (physics, hybrid, arm) identifies its model on
      (:class:`~ftdrake.compensation.estimators.build.RobotOptions`: a URDF/SDF file or
      ``"ftdrake"``).
    model_options: values of the registry entries' options by name (``identify_mounting``,
      ``drive_gains``, ...; :func:`~ftdrake.compensation.estimators.registry.train_options`).
    target_units: one unit per target (a sequence or one comma-separated string); None:
      N/N·m for wrench axes, else N·m.
    seed: random state of the kinds that have one. jobs: parallel CV fits (-1: all cores).
    cluster: a Dask scheduler's address to run the grid search on (None: local processes).
    search_budget_s: a bound on the grid search's time (s, wall clock; None: none): no new
      candidate is started when it would pass it, and the best of those scored is chosen
      (:func:`~ftdrake.compensation.estimators.tuning.tune`); default
      :data:`SEARCH_BUDGET_S`.
    max_rows: fit on at most this many rows covering the log's states
      (:func:`~ftdrake.data.subsample.covering_rows`); None: all rows.
    delay_s: the wrench stream's delay behind the joint states (s; negative: ahead),
      corrected in training and kept in the model (the chain applies it live).
    align: estimate that delay with the model fitted once, and correct it (not with `delay_s`).
    domain_holdout: a hybrid's out-of-domain std calibrated on this share of the rows, held out
      (whole runs, those farthest from the others), then refitted on all rows; e.g. 0.2.
    domain_calibration: ... or on this contact-free log (a file or a DataFrame, read with the
      same `read` options, not trained on). Not with `domain_holdout`.
    domain_shared_growth: with a domain calibration, one growth of the std for all axes.
    domain_level: with a domain calibration, where the std's level next to the data comes
      from: ``cross_fit`` (the fit's) or ``held_out`` (the calibration rows too).
    read: how the log is read (:class:`~ftdrake.data.training.ReadOptions`).
    t_start, t_end: keep the rows of this time window (s, on the log's own axis).
    motion_std: wrap the fitted model in a
      :class:`~ftdrake.compensation.estimators.motion_std.MotionStdCompensator` (a std that
      grows with ‖q̇‖ and ‖q̈‖, fitted from its training residuals). Not with a domain
      calibration.
    """

    kind: str | None = None
    features: str | None = None
    preset: str = "quick"
    robot: str | None = None
    sensor_frame: str | None = None
    base_frame: str | None = None
    joints: Any = None
    fixed_joints: Any = None
    model_options: Mapping[str, Any] = dc.field(default_factory=dict)
    target_units: Any = None
    seed: int = 0
    jobs: int | None = -1
    cluster: str | None = None
    search_budget_s: float | None = SEARCH_BUDGET_S
    max_rows: int | None = None
    delay_s: float | None = None
    align: bool = False
    domain_holdout: float | None = None
    domain_calibration: Any = None
    domain_shared_growth: bool = False
    domain_level: str = "cross_fit"
    read: ReadOptions = dc.field(default_factory=ReadOptions)
    t_start: float | None = None
    t_end: float | None = None
    motion_std: bool = False

    def __post_init__(self):
        self._check_choices()
        self._check_numbers()
        self._check_combinations()

    def _check_choices(self) -> None:
        for name, value, allowed in (("kind", self.kind, registry.names()),
                                     ("features", self.features, FEATURE_SETS),
                                     ("preset", self.preset, PRESETS),
                                     ("domain_level", self.domain_level, IN_DOMAIN_SOURCES)):
            if value is not None and value not in allowed:
                raise ConfigError(f"{spelled_option(name)}: {value!r} is not one of "
                                  f"{', '.join(map(str, allowed))}")
        if not isinstance(self.read, ReadOptions):
            raise ConfigError(f"{spelled_option('read')}: expected a ReadOptions; got "
                              f"{type(self.read).__name__}")
        calibration = self.domain_calibration
        if isinstance(calibration, (str, Path)) and not Path(calibration).exists():
            raise ConfigError(f"{spelled_option('domain_calibration')}: "
                                  f"{self.domain_calibration}: no such file or folder")

    def _check_numbers(self) -> None:
        if self.max_rows is not None and (isinstance(self.max_rows, bool)
                                          or not isinstance(self.max_rows, (int, np.integer))
                                          or self.max_rows < 1):
            raise ConfigError(f"{spelled_option('max_rows')}: must be a positive integer; got "
                              f"{self.max_rows!r}")
        if self.domain_holdout is not None and not 0 < self.domain_holdout < 0.5:
            raise ConfigError(f"{spelled_option('domain_holdout')}: must be a share in (0, 0.5) "
                              f"of the rows; got {self.domain_holdout!r}")
        budget = self.search_budget_s
        if budget is not None and (isinstance(budget, bool) or not isinstance(
                budget, (int, float, np.integer, np.floating)) or not 0 <= budget < np.inf):
            raise ConfigError(f"{spelled_option('search_budget_s')}: must be a non-negative "
                              f"number of seconds (0: score only the first candidate); got "
                              f"{budget!r}")
        if self.delay_s is not None and not np.isfinite(self.delay_s):
            raise ConfigError(f"{spelled_option('delay_s')}: must be a finite number of "
                              f"seconds; got {self.delay_s!r}")

    def _check_combinations(self) -> None:
        if self.delay_s is not None and self.align:
            raise ConfigError(f"{spelled_option('delay_s')} and {spelled_option('align')}: "
                              "give the delay or estimate it, not both")
        domain = self.domain_holdout is not None or self.domain_calibration is not None
        if self.motion_std and domain:
            raise ConfigError(f"{spelled_option('motion_std')} and a domain calibration: the "
                              "std is the motion's or the domain's, not both; leave one out")
        if self.domain_holdout is not None and self.domain_calibration is not None:
            raise ConfigError(f"{spelled_option('domain_holdout')} and "
                              f"{spelled_option('domain_calibration')}: calibrate on held-out "
                              "rows or on another log, not both")
        for name, given in (("domain_shared_growth", self.domain_shared_growth),
                            ("domain_level", self.domain_level != "cross_fit")):
            if given and not domain:
                raise ConfigError(f"{spelled_option(name)} needs "
                                  f"{spelled_option('domain_holdout')} or "
                                  f"{spelled_option('domain_calibration')}")

    def units_for(self, names: list[str]) -> list[str] | None:
        """The units of targets `names` given by :attr:`target_units` (None: not given)."""
        units = self.target_units
        if not units:
            return None
        units = [u.strip() for u in units.split(",")] if isinstance(units, str) else list(units)
        if len(units) != len(names):
            raise ConfigError(f"{spelled_option('target_units')} gives {len(units)} units for "
                              f"{len(names)} targets {names}")
        return units
