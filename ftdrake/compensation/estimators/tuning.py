"""Hyper-parameter search for compensators: the study's grids, and folds that respect time.

The study tuned every model with a 5-fold grid search over shuffled rows, repeated and
averaged. Rows of a trajectory log are not independent, though: a row 10 ms away from a
training row is nearly a copy of it, so shuffled folds reward memorising the trajectory. By
default the folds here are *grouped*: each trajectory is cut into contiguous time segments and
a segment never straddles training and validation. ``cv="shuffled"`` gives the study's folds.

Scoring is negative mean squared error (larger is better), in the targets' units squared;
when several outputs are tuned together their MSEs are averaged, so the force axes (N²)
dominate the torque axes ((N·m)²). ``per_output=True`` tunes every axis on its own, as the
study did.

Typical use::

    groups = segment_groups(trajectory_ids)          # one id per row, rows in time order
    model, result = tune(RandomForestCompensator(), X, Y, groups=groups, per_output=True)
    print(result.to_dict())
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import ClassVar

import numpy as np
from joblib import Parallel, delayed, parallel_config
from sklearn.base import clone
from sklearn.model_selection import GroupKFold, ParameterGrid, RepeatedKFold
from tqdm.auto import tqdm

from ..features import check_feature_set, describe_nonfinite, joints_in_layout
from .base import Compensator
from .registry import REGISTRY, entry_for

#: Names of the tuning presets; each registered compensator may have a grid for each
#: (:attr:`~ftdrake.compensation.estimators.registry.CompensatorEntry.presets`).
PRESET_NAMES = ("paper", "quick")

#: With ``groups=None`` the rows are cut into this many contiguous segments per fold.
SEGMENTS_PER_FOLD = 4


# -- grids --------------------------------------------------------------------------------
def param_grid(preset, estimator, n_features: int | None = None) -> list[dict]:
    """The grid of `preset` (a name in :data:`PRESET_NAMES`, or a grid itself) for `estimator`
    (an instance, class, class name or registry name).

    `n_features` is the number of input columns the estimator will use; integer
    ``max_features`` values above it are dropped (sklearn refuses them).
    """
    if isinstance(preset, str):
        if preset not in PRESET_NAMES:
            raise ValueError(f"unknown preset {preset!r}; expected one of {list(PRESET_NAMES)}")
        grid = presets_of(estimator).get(preset)
        if grid is None:
            with_grid = [e.name for e in REGISTRY.values() if preset in e.presets]
            raise ValueError(
                f"preset {preset!r} has no grid for {entry_for(estimator).name}; "
                f"compensators with one: {with_grid}"
            )
    else:
        grid = [preset] if isinstance(preset, dict) else list(preset)
    return [_clip_max_features(g, n_features) for g in grid]


def presets_of(estimator) -> dict[str, list[dict]]:
    """The tuning grids of a compensator (instance, class, class name or registry name)."""
    if isinstance(estimator, str) and estimator in REGISTRY:
        return dict(REGISTRY[estimator].presets)
    return dict(entry_for(estimator).presets)


def _clip_max_features(grid: dict, n_features: int | None) -> dict:
    if n_features is None or "max_features" not in grid:
        return dict(grid)
    kept = [m for m in grid["max_features"] if not isinstance(m, int) or m <= n_features]
    if not kept:
        raise ValueError(
            f"no max_features candidate in {grid['max_features']} fits {n_features} features"
        )
    return {**grid, "max_features": kept}


def grid_size(preset, estimator, n_features: int | None = None) -> int:
    """Number of candidates in a preset's grid (e.g. ``grid_size("paper", "SVRCompensator")``)."""
    return len(ParameterGrid(param_grid(preset, estimator, n_features)))


# -- folds --------------------------------------------------------------------------------
def segment_groups(trajectory, n_segments: int = 20) -> np.ndarray:
    """Group label per row: each trajectory cut into `n_segments` contiguous time segments.

    `trajectory` holds one trajectory id per row; within a trajectory, rows must be in time
    order. A trajectory with fewer rows than `n_segments` gets one segment per row.
    """
    trajectory = np.asarray(trajectory).ravel()
    if n_segments < 1:
        raise ValueError(f"n_segments must be at least 1; got {n_segments}")
    labels = np.empty(len(trajectory), dtype=np.int64)
    next_label = 0
    for traj in np.unique(trajectory):
        rows = np.flatnonzero(trajectory == traj)
        for chunk in np.array_split(rows, min(n_segments, len(rows))):
            labels[chunk] = next_label
            next_label += 1
    return labels


def cv_splits(
    n_rows: int,
    *,
    cv: str = "grouped",
    groups=None,
    n_splits: int = 5,
    n_repeats: int = 1,
    random_state: int = 0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """All (train_rows, test_rows) pairs of `n_repeats` rounds of `n_splits`-fold CV.

    ``cv="grouped"``: rows sharing a group label never fall on both sides; ``groups=None``
    cuts the rows, taken as one time-ordered trajectory, into ``SEGMENTS_PER_FOLD·n_splits``
    segments. ``cv="shuffled"``: the study's K-fold over shuffled rows.
    """
    if n_splits < 2:
        raise ValueError(f"n_splits must be at least 2; got {n_splits}")
    if n_repeats < 1:
        raise ValueError(f"n_repeats must be at least 1; got {n_repeats}")
    if n_rows < n_splits:
        raise ValueError(
            f"{n_splits}-fold cross-validation needs at least {n_splits} rows; got {n_rows}"
        )
    rows = np.zeros((n_rows, 1))  # splitters only look at the row count
    if cv == "shuffled":
        splitter = RepeatedKFold(n_splits=n_splits, n_repeats=n_repeats, random_state=random_state)
        return list(splitter.split(rows))
    if cv != "grouped":
        raise ValueError(f"unknown cv {cv!r}; expected 'grouped' or 'shuffled'")
    if groups is None:
        groups = segment_groups(np.zeros(n_rows), SEGMENTS_PER_FOLD * n_splits)
    groups = np.asarray(groups).ravel()
    if len(groups) != n_rows:
        raise ValueError(f"groups has {len(groups)} labels for {n_rows} rows")
    n_groups = len(np.unique(groups))
    if n_groups < n_splits:
        raise ValueError(
            f"cv='grouped' with n_splits={n_splits} needs at least {n_splits} groups "
            f"(trajectory segments); got {n_groups}. Cut trajectories finer with "
            "segment_groups(trajectory_ids, n_segments=...), add data, or lower n_splits"
        )
    return [
        split
        for r in range(n_repeats)
        for split in GroupKFold(n_splits, shuffle=True, random_state=random_state + r).split(
            rows, groups=groups
        )
    ]


# -- search -------------------------------------------------------------------------------
@dataclass
class TuneResult:
    """What a search found. Scores are negative MSE (targets' units squared), per target.

    ``targets`` names each tuned problem: every target column if ``per_output``, else one
    entry ``"all"``. ``best_params``, ``mean_score``, ``std_score`` (over all folds of all
    rounds) and ``candidates`` (every candidate's params, mean and std; None for a candidate
    not scored) follow that order. ``time_budget_s``: the search's time budget (s; None: no
    bound); ``scored``: candidates scored per target (``n_candidates`` each unless the budget
    stopped the search); ``stopped_after_s``: when the budget stopped it, the seconds it had
    run (None otherwise): the best was chosen among the candidates scored.
    """

    estimator: str
    preset: str
    cv: str
    n_splits: int
    n_repeats: int
    n_candidates: int
    targets: list[str]
    best_params: list[dict]
    mean_score: list[float]
    std_score: list[float]
    candidates: list[dict]
    time_budget_s: float | None = None
    scored: list[int] | None = None
    stopped_after_s: float | None = None

    @property
    def stopped_early(self) -> bool:
        """Whether the time budget stopped the search before every candidate was scored."""
        return self.stopped_after_s is not None

    def to_dict(self) -> dict:
        """JSON-ready copy."""
        return asdict(self)


def tune(
    estimator: Compensator,
    X,
    y,
    *,
    groups=None,
    preset="quick",
    cv: str = "grouped",
    n_splits: int = 5,
    n_repeats: int = 1,
    per_output: bool = False,
    target_names=None,
    n_jobs: int | None = None,
    progress: bool = True,
    random_state: int = 0,
    wrench_delay_s: float | None = None,
    time_budget_s: float | None = None,
):
    """Grid search with (grouped) repeated K-fold CV; returns ``(best_model, TuneResult)``.

    The best model is refitted on all rows. With ``per_output=True`` and several target
    columns, each column gets its own search and the model is a :class:`PerOutputCompensator`
    of one tuned estimator per column. `preset` is a name in :data:`PRESET_NAMES` or a grid.
    See :func:`cv_splits` for `cv`, `groups`, `n_splits`, `n_repeats`. `wrench_delay_s`:
    the refitted model's (:meth:`~.base.Compensator.fit`).

    `time_budget_s`: a bound on the search's time (s, wall clock; None: none). Candidates are
    then scored one after the other, in the grid's order, each on all its folds; the next is
    not started when the time so far plus the mean time of a candidate would pass the budget
    (every target gets its first candidate, so 0 scores exactly one). The best is chosen among
    the candidates scored; the result says how many (``scored``, ``stopped_after_s``).
    """
    if time_budget_s is not None and not (np.isfinite(time_budget_s) and time_budget_s >= 0):
        raise ValueError(f"time_budget_s must be a non-negative number of seconds (or None); "
                         f"got {time_budget_s!r}")
    X, Y = _checked_data(X, y)
    blocks = check_feature_set(estimator.get_params()["features"])
    n_used = blocks * joints_in_layout(X.shape[1])
    candidates = list(ParameterGrid(param_grid(preset, estimator, n_used)))
    splits = cv_splits(
        len(X),
        cv=cv,
        groups=groups,
        n_splits=n_splits,
        n_repeats=n_repeats,
        random_state=random_state,
    )
    if per_output:
        targets = [Y[:, j] for j in range(Y.shape[1])]
        names = _target_names(target_names, Y.shape[1])
    else:
        targets, names = [Y[:, 0] if np.ndim(y) == 1 else Y], ["all"]

    with tqdm(
        total=len(targets) * len(candidates) * len(splits),
        disable=not progress,
        desc=f"tuning {type(estimator).__name__}",
        unit="fit",
    ) as bar:
        clock = _Budget(time_budget_s)
        scores = [_score_grid(estimator, X, t, candidates, splits, n_jobs, bar, clock)
                  for t in targets]

    scored = [np.isfinite(s).all(axis=1) for s in scores]
    best = [int(np.flatnonzero(ok)[np.argmax(s[ok].mean(axis=1))])
            for s, ok in zip(scores, scored, strict=True)]
    model = _refit(estimator, X, y, Y, [candidates[b] for b in best], per_output,
                   wrench_delay_s)
    result = TuneResult(
        estimator=type(estimator).__name__,
        preset=preset if isinstance(preset, str) else "custom",
        cv=cv,
        n_splits=n_splits,
        n_repeats=n_repeats,
        n_candidates=len(candidates),
        targets=names,
        best_params=[_jsonable(candidates[b]) for b in best],
        mean_score=[float(s[b].mean()) for s, b in zip(scores, best, strict=True)],
        std_score=[float(s[b].std()) for s, b in zip(scores, best, strict=True)],
        candidates=[
            {
                "params": [_jsonable(p) for p in candidates],
                "mean_score": _or_none(s.mean(axis=1)),
                "std_score": _or_none(s.std(axis=1)),
            }
            for s in scores
        ],
        time_budget_s=None if time_budget_s is None else float(time_budget_s),
        scored=[int(ok.sum()) for ok in scored],
        stopped_after_s=(round(clock.elapsed(), 1)
                         if any(not ok.all() for ok in scored) else None),
    )
    return model, result


class _Budget:
    """The search's clock: whether another candidate fits in the time budget."""

    def __init__(self, budget_s: float | None):
        self.budget_s = budget_s
        self.started = time.perf_counter()
        self.candidates = 0

    def elapsed(self) -> float:
        return time.perf_counter() - self.started

    def done(self) -> None:
        self.candidates += 1

    def allows_another(self) -> bool:
        """True without a budget; else whether the time so far plus the mean candidate's
        stays within it."""
        if self.budget_s is None:
            return True
        elapsed = self.elapsed()
        return elapsed + elapsed / max(self.candidates, 1) <= self.budget_s


def _or_none(values: np.ndarray) -> list:
    """A JSON-ready list; NaN (a candidate not scored) as None."""
    return [None if not np.isfinite(v) else float(v) for v in values]


def _checked_data(X, y) -> tuple[np.ndarray, np.ndarray]:
    X = np.asarray(X, dtype=float)
    Y = np.asarray(y, dtype=float)
    if X.ndim != 2:
        raise ValueError(f"X must be 2-D (rows × 3n); got shape {X.shape}")
    Y = Y.reshape(len(Y), -1)
    if len(X) != len(Y):
        raise ValueError(f"X has {len(X)} rows but y has {len(Y)}")
    for arr, name in ((X, "X"), (Y, "y")):
        message = describe_nonfinite(arr, name)
        if message:
            raise ValueError(message)
    return X, Y


def _target_names(target_names, n: int) -> list[str]:
    if target_names is None:
        return [f"y{j}" for j in range(n)]
    target_names = [str(t) for t in target_names]
    if len(target_names) != n:
        raise ValueError(f"{len(target_names)} target names for {n} target columns")
    return target_names


def _score_grid(estimator, X, y, candidates, splits, n_jobs, bar, clock=None) -> np.ndarray:
    """(n_candidates, n_splits) array of negative MSE on the held-out rows; NaN rows for
    candidates `clock` (a :class:`_Budget` with a budget) left unscored."""
    scores = np.full((len(candidates), len(splits)), np.nan)
    if clock is None or clock.budget_s is None:
        _score_candidates(estimator, X, y, candidates, range(len(candidates)), splits, n_jobs,
                          bar, scores)
        return scores
    for c in range(len(candidates)):
        if c > 0 and not clock.allows_another():
            break
        _score_candidates(estimator, X, y, candidates, [c], splits, n_jobs, bar, scores)
        clock.done()
    return scores


def _score_candidates(estimator, X, y, candidates, which, splits, n_jobs, bar, scores):
    """Fills the rows `which` of `scores` (every fold of those candidates, in parallel)."""
    tasks = (
        delayed(_fit_and_score)(estimator, candidates[c], X, y, train, test, (c, s))
        for c in which
        for s, (train, test) in enumerate(splits)
    )
    for (c, s), score in Parallel(n_jobs=n_jobs, return_as="generator_unordered")(tasks):
        scores[c, s] = score
        bar.update()


def _fit_and_score(estimator, params, X, y, train, test, key):
    # One fit is one task: on a Dask cluster, joblib would otherwise ship every tree of a
    # forest back to the cluster as its own tiny task (measured: 29 s → 7 s quick search).
    with parallel_config(backend="sequential"):
        model = clone(estimator).set_params(**params).fit(X[train], y[train])
    error = model.predict(X[test]) - y[test]
    return key, -float(np.mean(error**2))


def _refit(estimator, X, y, Y, best_params, per_output, wrench_delay_s=None):
    if per_output and Y.shape[1] > 1:
        members = [clone(estimator).set_params(**p) for p in best_params]
        features = estimator.get_params()["features"]
        return PerOutputCompensator(members, features=features).fit(
            X, Y, wrench_delay_s=wrench_delay_s)
    return clone(estimator).set_params(**best_params[0]).fit(X, y,
                                                             wrench_delay_s=wrench_delay_s)


def _jsonable(params: dict) -> dict:
    return {k: v.item() if isinstance(v, np.generic) else v for k, v in params.items()}


# -- one estimator per output ---------------------------------------------------------------
class PerOutputCompensator(Compensator):
    """One compensator per target column, each with its own hyper-parameters.

    What per-axis tuning returns: the study tuned each wrench axis on its own.

    Parameters
    ----------
    estimators : list of Compensator
        One unfitted estimator per target column, in column order. Their feature sets must be
        contained in `features`.
    features : {"q", "q,qd", "q,qd,qdd"}
        The widest feature set of the members; it defines ``out_of_domain``.

    Fitted attributes
    -----------------
    estimators_ : list of fitted Compensator, each predicting one column.
    """

    _parameter_constraints: ClassVar[dict] = {
        **Compensator._parameter_constraints,
        "estimators": [list, tuple],
    }

    def __init__(self, estimators, features: str = "q,qd,qdd"):
        self.estimators = estimators
        self.features = features

    def _fit(self, Z: np.ndarray, Y: np.ndarray) -> None:
        if len(self.estimators) != Y.shape[1]:
            raise ValueError(f"{len(self.estimators)} estimators for {Y.shape[1]} target columns")
        widest = check_feature_set(self.features)
        for member in self.estimators:
            if check_feature_set(member.get_params()["features"]) > widest:
                raise ValueError(
                    f"a member uses features {member.get_params()['features']!r}, wider than "
                    f"this compensator's {self.features!r}"
                )
        X = self._full_layout(Z)
        self.estimators_ = [clone(e).fit(X, Y[:, j]) for j, e in enumerate(self.estimators)]

    def _predict(self, Z: np.ndarray) -> np.ndarray:
        X = self._full_layout(Z)
        return np.column_stack([e.predict(X) for e in self.estimators_])

    def row_predictor(self):
        """The members' row predictors, one output column each."""
        members = [e.row_predictor() for e in self.estimators_]

        def predict(row):
            parts = [member(row) for member in members]
            return (np.array([float(np.ravel(mean)[0]) for mean, _ in parts]),
                    np.array([float(np.ravel(std)[0]) for _, std in parts]))

        return predict

    def _full_layout(self, Z: np.ndarray) -> np.ndarray:
        # Members select their own blocks from [q, qd, qdd]; blocks this compensator does not
        # use are never read by them, so zeros are a safe filler.
        missing = 3 * self.n_joints_ - Z.shape[1]
        return np.hstack([Z, np.zeros((len(Z), missing))])
