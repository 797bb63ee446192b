"""`ftdrake.train`: the one training pipeline — read, align the streams, subsample, tune or
fit, calibrate the out-of-domain std, record the provenance.

    result = ftdrake.train("id1.csv", kind="physics", robot="arm.urdf", sensor_frame="ft")
    result.save("m.ftd")           # the model file, its manifest keeping result.provenance

The ``ftdrake train`` command parses its flags into a :class:`~.options.TrainOptions`, calls
:func:`train` and prints; everything it does is here.
"""

from __future__ import annotations

import dataclasses as dc
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
from sklearn.base import clone

from ..compensation.calibration.calibration import static_table_hint
from ..compensation.estimators import registry
from ..compensation.estimators.build import BUILTIN_ROBOT, RobotOptions, is_wrench
from ..compensation.estimators.domain import MIN_GROUPS
from ..compensation.estimators.domain_calibrated import DomainCalibratedHybrid
from ..compensation.estimators.hybrid import HybridCompensator
from ..compensation.estimators.motion_std import MotionStdCompensator
from ..compensation.estimators.robot_file import check_robot_frames
from ..compensation.estimators.tuning import segment_groups, tune
from ..compensation.features import check_feature_set
from ..compensation.files.persistence import save_model
from ..conventions import WRENCH_UNITS
from ..data.stream_delay import align_training_data, estimate_training_delay
from ..data.subsample import OVERSAMPLE, covering_rows
from ..data.training import IN_MEMORY, TrainingData, load_training_data
from ..errors import ConfigError, FtdrakeError, LogError, RobotModelError
from ..parallel import dask_backend
from .imu_rows import with_imu_columns
from .notes import kept_rows, residual_gain, residual_gain_text
from .options import TrainOptions, spelled_option
from .provenance import provenance

Say = Callable[[str], None]


@dc.dataclass
class TrainResult:
    """A fitted model and what its file keeps about how it was made.

    model: the fitted compensator (a :class:`~ftdrake.compensation.estimators.domain_calibrated.
    DomainCalibratedHybrid` around the hybrid with a domain calibration). provenance: the
    manifest's ``extra`` (data file and read options, columns, ranges, row counts, reader
    warnings, parameters, tuning, and the subsample, domain calibration and stream delay when
    done). target_names, target_units, sensor_frame: what the outputs are. data: the rows
    fitted on (after alignment and subsampling). search: the grid search's result (None
    without one). summary: the identified payload, as lines (physics and hybrid; else None).
    """

    model: object
    provenance: dict
    target_names: list[str]
    target_units: list[str]
    sensor_frame: str
    data: TrainingData
    search: object = None
    summary: str | None = None

    def save(self, path) -> Path:
        """Writes the model file (:func:`~ftdrake.compensation.files.persistence.save_model`)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        return save_model(self.model, path, target_names=self.target_names,
                          target_units=self.target_units, sensor_frame=self.sensor_frame,
                          extra=self.provenance)


def train(data, options: TrainOptions | None = None, *, progress: Say | None = None,
          warn: Say | None = None, **fields) -> TrainResult:
    """Fits a compensator on `data` as `options` say; returns the model and its provenance.

    `data`: a log file (CSV/Parquet table, ROS 1 ``.bag`` file or ROS 2 bag folder), a
    ``pandas.DataFrame`` of a table, or a :class:`~ftdrake.data.training.TrainingData`
    already read. `options`: a :class:`~.options.TrainOptions`, or its fields as keywords
    (``train(path, kind="rf", max_rows=5000)``; keywords given with `options` override its
    fields). `progress`: called with each progress line (None: silent); `warn`: with each
    warning about the data (rows the reader dropped, ...; None: only kept in the
    provenance's ``reader_warnings``).

    Raises :class:`~ftdrake.errors.FtdrakeError` subclasses naming the option that fixes
    the problem (:func:`~.options.spelled_option`).
    """
    options = dc.replace(options, **fields) if options is not None else TrainOptions(**fields)
    say = progress or _silent
    if options.robot and options.robot != BUILTIN_ROBOT and options.sensor_frame:
        # Frames are checked before the data is read: a long read would be thrown away.
        check_robot_frames(options.robot, options.sensor_frame, options.base_frame)
    source = data
    data = _read(source, options, say, warn)
    kind, estimator = _estimator(options, data, say)
    if getattr(estimator, "needs_imu", False):
        data = with_imu_columns(source, data, options.read.time, options.read.group)
    units = options.units_for(data.target_names) or default_units(data.target_names)
    data, stream_delay = _align_streams(options, kind, data, estimator, say)
    data, subsample = _subsample(options, data, estimator, say)
    delay = None if stream_delay is None else stream_delay["delay_s"]
    model, search = _tune_or_fit(options, kind, estimator, data, delay, say,
                                 bar=progress is not None)
    model, domain = _domain_calibration(options, model, data, say, warn)
    if options.motion_std:
        model = _with_motion_std(model, data, delay, say)
    gain = _report(model, data, say)
    extra = provenance(_source_name(source, data), data, model, search, kind=kind,
                       time_window=(options.t_start, options.t_end), dask=options.cluster)
    # The chain applies the stream delay live: it is fitted into the model (wrench_delay_s_).
    for key, value in (("subsample", subsample), ("domain_calibration", domain),
                       ("stream_delay", stream_delay), ("residual_gain", gain)):
        if value is not None:
            extra[key] = value
    sensor_frame = options.sensor_frame or ("S" if is_wrench(data.target_names) else "joints")
    summary = model.summary() if hasattr(model, "summary") else None
    return TrainResult(model, extra, list(data.target_names), units, sensor_frame, data,
                       search, summary)


def _estimator(options: TrainOptions, data: TrainingData, say: Say):
    """(the registry name, the unfitted compensator) the options ask for on `data`."""
    robot = RobotOptions(options.robot, options.sensor_frame, options.base_frame,
                         data.scenario_yaml, joints=options.joints,
                         fixed_joints=options.fixed_joints)
    kind = options.kind
    if kind is None:
        kind = registry.default_kind(robot)
        say(f"{spelled_option('kind')} not given: {kind} "
            + ("(a robot description and wrench targets: physics + learned residual)"
               if kind == "hybrid" else f"(no {spelled_option('robot')}: a black box)"))
    estimator = registry.make_estimator(kind, features=options.features, seed=options.seed,
                                        target_names=data.target_names, robot=robot,
                                        options=options.model_options)
    for name in ("domain_holdout", "domain_calibration"):
        if getattr(options, name) is not None:
            _needs_hybrid(estimator, name)
    return kind, estimator


def _with_motion_std(model, data: TrainingData, delay, say: Say):
    """The fitted `model`'s kind and parameters refitted inside a std of the motion."""
    say(f"fitting a std of the motion (‖q̇‖, ‖q̈‖) on the residuals of {len(data.X)} rows …")
    wrapped = MotionStdCompensator(clone(model))
    return wrapped.fit(data.X, data.Y, **({} if delay is None else {"wrench_delay_s": delay}))


def _domain_calibration(options: TrainOptions, model, data: TrainingData, say: Say,
                        warn: Say | None):
    """(the model, calibrated on another log when asked; what the manifest keeps about its
    domain calibration, or None without one)."""
    domain = None
    if options.domain_calibration is not None:
        model, domain = _calibrate_domain(options, model, data, say, warn)
    elif options.domain_holdout is not None:
        domain = dict(model.domain_calibration_)
    if domain is not None:
        _say_domain(domain, say)
    return model, domain


def _report(model, data: TrainingData, say: Say) -> dict | None:
    """Says what the model kept of the rows and what a hybrid's residual gained over its
    physics part; returns the latter (:func:`~.notes.residual_gain`) or None."""
    kept = kept_rows(model, len(data.X))
    if kept is not None:
        say(kept)
    gain = residual_gain(model)
    if gain is not None:
        say(residual_gain_text(gain, data.target_names))
    return gain


def _silent(_message: str) -> None:
    pass


def default_units(names: list[str]) -> list[str]:
    """N/N·m for a wrench's targets, else N·m for each."""
    return list(WRENCH_UNITS) if is_wrench(names) else ["N*m"] * len(names)


def _read(source, options: TrainOptions, say: Say, warn: Say | None) -> TrainingData:
    if isinstance(source, TrainingData):
        return source
    name = IN_MEMORY if isinstance(source, pd.DataFrame) else source
    say(f"reading {name} …")
    try:
        data = load_training_data(source, options.read, t_start=options.t_start,
                                  t_end=options.t_end, report=warn, static_poses=False)
    except LogError as e:
        hint = (None if isinstance(source, pd.DataFrame)
                else static_table_hint(source, options.read.time, options.read.positions))
        if hint is None:
            raise
        raise LogError(f"{e}; {hint}") from None
    say(describe(data))
    return data


def _source_name(source, data: TrainingData) -> str:
    """What the provenance calls the data: the path as given, else what it was."""
    if isinstance(source, TrainingData):
        return data.source
    return IN_MEMORY if isinstance(source, pd.DataFrame) else str(source)


def _tune_or_fit(options: TrainOptions, kind: str, estimator, data: TrainingData, delay, say,
                 *, bar: bool):
    """(the fitted model, the search's result or None); `bar`: the search's progress bar."""
    if options.preset == "quick" and "quick" in registry.entry(kind).presets:
        where = f"Dask scheduler {options.cluster}" if options.cluster else "local processes"
        say(f"tuning {kind} (quick grid, grouped 5-fold CV) on {where} …")
        with dask_backend(options.cluster):
            model, search = tune(estimator, data.X, data.Y, groups=segment_groups(data.groups),
                                 preset="quick", cv="grouped", target_names=data.target_names,
                                 n_jobs=options.jobs, progress=bar,
                                 wrench_delay_s=delay, time_budget_s=options.search_budget_s)
        if search.stopped_early:
            say(search_stopped_text(search))
        say(f"best {search.best_params[0]}, CV MSE {-search.mean_score[0]:.4g}")
        return model, search
    why = "" if options.preset == "none" else " (no grid: its parameters are fitted from data)"
    say(f"fitting {kind}{why} on {len(data.X)} rows …")
    started = time.perf_counter()
    model = fit(estimator, data, needs_robot=registry.entry(kind).needs_robot,
                holdout=options.domain_holdout, shared_growth=options.domain_shared_growth,
                in_domain=options.domain_level, wrench_delay_s=delay)
    say(f"fitted in {time.perf_counter() - started:.1f} s")
    return model, None


def search_stopped_text(search) -> str:
    """What a search the time budget stopped says: how far it got, and what to change."""
    scored = min(search.scored)
    return (f"the search stopped early: {scored} of {search.n_candidates} candidates scored "
            f"in {search.stopped_after_s:.0f} s, and the next would have passed the time "
            f"budget of {search.time_budget_s:g} s ({spelled_option('search_budget_s')}); "
            f"the best of those {scored} was chosen. For the whole grid raise the budget, "
            f"or fit on fewer rows ({spelled_option('max_rows')})")


def _subsample(options: TrainOptions, data: TrainingData, estimator, say: Say):
    """max_rows: (data cut to the covering rows, what was done) or (data, None)."""
    if options.max_rows is None or len(data.X) <= options.max_rows:
        return data, None
    features = getattr(estimator, "features", None)
    columns = check_feature_set(features) * data.n_joints if features else None
    say(f"choosing {options.max_rows} of {len(data.X)} rows that cover the log's states …")
    started = time.perf_counter()
    rows = covering_rows(data.X, options.max_rows, groups=data.groups, columns=columns)
    elapsed = time.perf_counter() - started
    say(f"chose {len(rows)} rows in {elapsed:.1f} s")
    done = {"rows_in": len(data.X), "rows_used": len(rows), "max_rows": options.max_rows,
            "method": "every k-th row, then farthest-point in the model's scaled inputs",
            "oversample": OVERSAMPLE, "metric_columns": columns or data.X.shape[1]}
    return dc.replace(data, X=data.X[rows], Y=data.Y[rows], t=data.t[rows],
                      groups=data.groups[rows], rows=dict(data.rows, used=len(rows))), done


def _align_streams(options: TrainOptions, kind: str, data: TrainingData, estimator, say: Say):
    """delay_s / align: (data with the targets moved the delay earlier, the delay as a
    dict) or (data, None) without either (:mod:`ftdrake.data.stream_delay`)."""
    if options.delay_s is None and not options.align:
        return data, None
    if data.static:
        raise LogError(f"{spelled_option('delay_s')}/{spelled_option('align')}: a table of "
                       "static poses has no time axis to align")
    if options.align:
        needs_robot = registry.entry(kind).needs_robot
        say(f"estimating the wrench stream's delay with {kind} …")
        estimate = estimate_training_delay(
            lambda d: fit(clone(estimator), d, needs_robot=needs_robot), data)
        found = estimate.as_dict()
        say(f"wrench stream delay: {estimate.delay_s * 1e3:.2f} ± {estimate.std_s * 1e3:.2f} ms "
            f"({estimate.samples:.2f} samples); corrected"
            + ("" if found["distinct_from_zero"] else " (within two standard errors of 0)"))
    else:
        found = {"delay_s": float(options.delay_s), "given": True}
    return align_training_data(data, found["delay_s"]), found


def fit(estimator, data: TrainingData, *, needs_robot: bool, holdout: float | None = None,
        shared_growth: bool = False, in_domain: str = "cross_fit",
        wrench_delay_s: float | None = None):
    """Fits `estimator` on `data` (with `holdout`, a
    :class:`~ftdrake.compensation.estimators.domain_calibrated.DomainCalibratedHybrid` around it,
    calibrated on that share of the runs). A robot-based model's ValueErrors are about the
    robot description (joint count, frames); they name the options that choose it."""
    def run():
        if holdout is None:
            return estimator.fit(data.X, data.Y, wrench_delay_s=wrench_delay_s)
        runs = data.groups if len(np.unique(data.groups)) >= MIN_GROUPS else None
        return DomainCalibratedHybrid(estimator, holdout=holdout, shared_growth=shared_growth,
                                      in_domain=in_domain).fit(
            data.X, data.Y, groups=runs, wrench_delay_s=wrench_delay_s)

    if not needs_robot:
        return run()
    try:
        return run()
    except FtdrakeError:
        raise
    except ValueError as e:
        names = ", ".join(spelled_option(n) for n in ("robot", "sensor_frame", "base_frame"))
        raise RobotModelError(f"{e} (check {names} and "
                              f"{spelled_option('read.positions')})") from e


def _needs_hybrid(model, option: str) -> None:
    residual = getattr(model, "residual", None)
    own_std = getattr(residual, "provides_std", False) and getattr(
        residual, "std_includes_noise", False)  # a GP residual: no support term
    if not isinstance(model, HybridCompensator) or own_std:
        raise ConfigError(f"{spelled_option(option)} is for {spelled_option('kind')} hybrid "
                          "with its forest residual (the support term of its std); omit it")


def _calibrate_domain(options: TrainOptions, model, data: TrainingData, say: Say,
                      warn: Say | None):
    """domain_calibration: `model` wrapped with its support term calibrated on that log;
    returns (the wrapper, what the manifest keeps about the calibration)."""
    source = options.domain_calibration
    name = IN_MEMORY if isinstance(source, pd.DataFrame) else source
    say(f"reading {name} (out-of-domain calibration) …")
    log = load_training_data(source, options.read, report=warn)
    if log.target_names != data.target_names or log.X.shape[1] != data.X.shape[1]:
        raise LogError(f"{spelled_option('domain_calibration')} {name}: its columns "
                       f"({log.target_names}) are not the training data's "
                       f"({data.target_names}); give a log of the same robot and sensor")
    calibrated = DomainCalibratedHybrid(model, shared_growth=options.domain_shared_growth,
                                        in_domain=options.domain_level).fit(log.X, log.Y)
    return calibrated, {"file": str(name), **calibrated.domain_calibration_}


def _say_domain(found: dict, say: Say) -> None:
    length = "∞" if found["length"] is None else f"{found['length']:.3g}"
    say(f"out-of-domain std: ℓ = {length}, g = "
        + ", ".join(f"{g:.3g}" for g in found["growth"])
        + "; 95 % coverage on the calibration rows "
        + ", ".join(f"{c:.2f}" for c in found["coverage_95_after"])
        + " (before: " + ", ".join(f"{c:.2f}" for c in found["coverage_95_before"]) + ")")


def describe(data: TrainingData) -> str:
    """One line: the rows used of those in the file, joints, targets, derived columns."""
    r = data.rows
    methods = {"savitzky_golay": "Savitzky–Golay", "causal": "the loop's causal estimate"}
    derived = "".join(f"; {k} from {methods[v['method']]}" for k, v in data.derivation.items())
    return (f"{r['used']} rows used of {r['in_file']} in the file ({r['dropped_by_reader']} "
            f"dropped by the reader, {r['outside_time_window']} outside the time window), "
            f"{data.n_joints} joints, {len(data.target_names)} targets{derived}")
