"""The RF-vs-SVR study of F/T compensation, repeated on simulated data.

The study (Motoman SDA10D, one pre-defined slow trajectory, 13,745 rows) trained one random
forest (RF) and one SVR per wrench axis on three feature sets — ``q``, ``q,qd``, ``q,qd,qdd``
with q̇, q̈ numerically differentiated — and claimed: (a) RF beats SVR on every axis; (b) RF
barely changes when q̇, q̈ are added while SVR does; (c) Fz and Tz are worst, because the
trajectory hardly moves in Z — (e) more Z motion would help; (d) the RF relies on the joint
positions. :func:`check_findings` checks each against the numbers.

Here the same is done on two simulated datasets: ``reference`` (the study-like motion, little
Z) and ``z_rich`` (pitch joints moving, tool height and tilt changing). Differences from the
study, on purpose:

* Test rows come from *held-out trajectories*; no row of a test trajectory is trained on.
* Hyper-parameters are tuned with folds grouped by trajectory segment (``cv="grouped"``); the
  study's shuffled K-fold is ``cv="shuffled"``. Both are always run for RF on ``q`` to show how
  much they disagree with the held-out error.
* Three extra rows: SVR with standardised targets (ftdrake's default; the study's SVR has its
  ε-tube in N or N·m, wider than the whole signal of a small torque axis), the physics
  payload model alone, and physics + RF residual (hybrid, its residual forest not tuned).
  For the physics rows a feature set means the joint-state blocks the model may read: ``q`` is
  the static payload model (gravity, CoM, biases), ``q,qd`` the dynamic model with q̈ = 0,
  ``q,qd,qdd`` the full Newton-Euler model.
* Logs are 1 kHz; training rows are taken at ``train_hz`` (default 12.5 Hz: the motion is
  below 1 Hz, so denser rows are near copies, and it keeps the quick study short), test rows
  at ``test_hz`` (100 Hz). SVR trains on at most ``svr_max_rows`` rows,
  evenly spaced in time (the quick defaults stay below it).

Metrics per axis on the test rows: MSE (N², (N·m)²), NMSE = MSE / var(measured), variance score
(the study's three, against the *measured* wrench), and — what simulation adds — the RMS of the
prediction against the true internal wrench (N, N·m) and that over the sensor's noise σ.

Typical use::

    results = run_study("out/study")          # the quick grid
    for f in results["findings"]:
        print(f["claim"], f["reproduced"], f["evidence"])

The package, by the data path:

* :mod:`.layout` — what the tables hold: datasets, methods, feature sets, axes, metrics,
  figures, and the study's published Table 2.
* :mod:`.settings` — what is tuned, the quick run's defaults, each method's grid.
* :mod:`.run` — :func:`run_study`; the split, the tuning and scoring of each method, the
  derived tables (CV disagreement, importances, tool-tip extent).
* :mod:`.estimate` — :func:`estimate_seconds`, the run's time estimate.
* :mod:`.findings` — :func:`check_findings`: each claim's verdict and numbers, no prose.
* :mod:`.report` — the prose chosen from those numbers, results.md; :mod:`.figures` — the
  figures.
* :mod:`.protocols` — the study repeated faithfully (its motion, tool and protocol beside
  ftdrake's); :mod:`.search` — its per-axis grid and halving search; :mod:`.paper` — the
  paper grid on a Dask cluster.

The command line (``ftdrake study``) is :mod:`ftdrake.cli.study`.
"""

from .estimate import estimate_seconds
from .figures import FIGURE_MAKERS, write_figures
from .findings import Q_SHARE, UNCHANGED_VS, Finding, check_findings
from .layout import AXES, DATASETS, FEATURES, FIGURES, METHODS, METRICS
from .report import CLAIMS, METHOD_LABELS, describe, finding_records, markdown
from .run import (
    Split,
    cv_disagreement,
    decimate,
    fx_importances,
    only,
    physical_model,
    prepare_split,
    run_study,
    split_trajectories,
    study_dataset,
    tool_tip_extent,
)
from .settings import (
    DURATION_S,
    HYBRID_RESIDUAL,
    N_SPLITS,
    PHYSICS_MODE,
    SEGMENT_S,
    SVR_MAX_ROWS,
    TEST_HZ,
    TEST_TRAJECTORIES,
    TRAIN_HZ,
    TRAJECTORIES,
    TUNED,
    grid_sizes,
)

__all__ = [
    "AXES", "CLAIMS", "DATASETS", "DURATION_S", "FEATURES", "FIGURES", "FIGURE_MAKERS",
    "HYBRID_RESIDUAL", "METHODS", "METHOD_LABELS", "METRICS", "N_SPLITS", "PHYSICS_MODE",
    "Q_SHARE", "SEGMENT_S", "SVR_MAX_ROWS", "TEST_HZ", "TEST_TRAJECTORIES", "TRAIN_HZ",
    "TRAJECTORIES", "TUNED", "UNCHANGED_VS", "Finding", "Split", "check_findings",
    "cv_disagreement", "decimate", "describe", "estimate_seconds", "finding_records",
    "fx_importances", "grid_sizes", "markdown", "only", "physical_model", "prepare_split",
    "run_study", "split_trajectories", "study_dataset", "tool_tip_extent", "write_figures",
]
