"""The study's paper grid on the study protocol, on a Dask cluster (``ftdrake study --paper``).

:func:`run_paper` collects the study trajectories, runs :func:`~.protocols.run_protocols`
with the paper's grid (exhaustive or successive halving) on the cluster's workers and writes
``paper.json`` and ``paper.md``; :func:`exhaustive_fits` and :func:`exhaustive_seconds` say
what the unreduced search would cost.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from dask.distributed import Client, LocalCluster
from joblib import parallel_config
from sklearn.model_selection import ParameterGrid

from ... import conventions as col
from ...compensation.estimators.tuning import param_grid
from ...config import ScenarioConfig
from ...io import atomic_path
from ...version import result_provenance
from .layout import AXES, FEATURES
from .protocols import collect_study, protocol_findings, run_protocols, study_scenario
from .report import protocols_markdown
from .search import grid_of


def exhaustive_fits(preset="paper", features=FEATURES, n_splits: int = 5) -> dict:
    """Fits an exhaustive grid search needs: candidates × folds × 6 axes, per method and set."""
    return {m: {f: len(ParameterGrid(param_grid(preset, m, col.N_JOINTS
                                                 * len(f.split(","))))) * n_splits * len(AXES)
                for f in features} for m in ("rf", "svr")}


def exhaustive_seconds(best: dict, *, train_rows: int, preset="paper", n_splits: int = 5,
                       n_jobs: int = 1) -> dict:
    """What exhaustive grid search would cost (s on `n_jobs` workers), per "method features",
    scaled from halving's last round (`best`: ``best_params["study"]``): RF from its seconds
    per tree (× every candidate's tree count), SVR from its mean fit at the last round's rows,
    × (rows / those rows)² (libsvm is about quadratic; capped fits make it a lower bound)."""
    out = {}
    for m, by_f in best.items():
        for f, per_axis in by_f.items():
            grid = list(ParameterGrid(grid_of(preset, m, col.N_JOINTS * len(f.split(",")))))
            total = 0.0
            for p in per_axis.values():
                last = p["last_round_mean_fit_s"] / max(_last_rows_share(p, train_rows), 1e-9)
                if m == "rf":
                    trees = sum(c["n_estimators"] for c in grid)
                    total += last / (p["n_resources"][-1] if p["resource"] == "n_estimators"
                                     else 1) * (trees if p["resource"] == "n_estimators"
                                                else len(grid)) * n_splits
                else:
                    total += last * len(grid) * n_splits
            # Not rounded here: a small grid's estimate is well under a second, and rounding
            # belongs to whoever prints it.
            out[f"{m} {f}"] = total / max(n_jobs, 1)
    return out


def _last_rows_share(p: dict, rows: int) -> float:
    """The last round's share of a full fit's cost: its rows over all `rows` (RF ~linear,
    SVR ~quadratic); 1 where the budget was trees (all rows were used)."""
    if p["resource"] != "n_samples":
        return 1.0
    share = p["n_resources"][-1] / rows
    return share**2 if "kernel" in p else share


def run_paper(out_dir, *, scheduler: str | None = None, features=("q",), search="halving",
              max_train_rows: int | None = None, protocols=("study", "study_on_new"),
              config: ScenarioConfig | None = None, seed: int = 0, n_workers: int = 2,
              progress: bool = True, halving: dict | None = None,
              command: str | None = None) -> dict:
    """The study's paper grid on the study protocol, on a Dask cluster at `scheduler` (or a
    LocalCluster of `n_workers`); writes ``paper.json`` and ``paper.md`` into `out_dir`.
    `halving` overrides :data:`~.search.HALVING`; `command` is the command line, for paper.md."""
    started = time.perf_counter()
    cluster = None if scheduler else LocalCluster(n_workers=n_workers, threads_per_worker=1,
                                                  processes=True, dashboard_address=None)
    address = scheduler or cluster.scheduler_address
    try:
        with Client(address) as client:
            workers = len(client.scheduler_info()["workers"])
        frame = collect_study(study_scenario(config), seed=seed, dask_address=address,
                              n_jobs=-1)
        collect_s = time.perf_counter() - started
        with Client(address), parallel_config(backend="dask"):
            res = run_protocols(frame, preset="paper", search=search, features=features,
                                max_train_rows=max_train_rows, seed=seed, n_jobs=-1,
                                progress=progress, protocols=protocols, halving=halving)
    finally:
        if cluster is not None:
            cluster.close()
    best = res["best_params"]["study"]
    out = {"results": res, "findings": protocol_findings(res), "cluster": address,
           "workers": workers, "command": command,
           "exhaustive_fits": exhaustive_fits("paper", features),
           "fitted_candidates": {k: {a: p.get("n_candidates_fitted") for a, p in v.items()}
                                 for k, v in _flat_params(best).items()},
           "collect_s": round(collect_s, 1),
           "wall_time_s": round(time.perf_counter() - started, 1),
           "provenance": result_provenance(command)}
    if search == "halving":
        out["exhaustive_s_estimate"] = exhaustive_seconds(
            best, train_rows=res["sizes"]["train_rows"], n_jobs=workers)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(out_dir / "paper.json") as tmp:
        tmp.write_text(json.dumps(out, indent=1))
    with atomic_path(out_dir / "paper.md") as tmp:
        tmp.write_text(paper_markdown(out, protocols_markdown(out)))
    return out


#: The paper grid without any reduction (weeks on 2 cores; see paper.md's estimate).
FULL_PAPER_COMMAND = ("ftdrake study --paper --search grid --svr-max-iter -1 "
                      "--features 'q;q,qd;q,qd,qdd' --cluster ADDRESS")


def paper_markdown(out: dict, protocols_section: str) -> str:
    """paper.md: the run's settings and reductions, the exhaustive estimate, the results."""
    res = out["results"]
    s, sizes = res["settings"], res["sizes"]
    h = s.get("halving", {})
    lines = [f"# The study's paper grid, `{s['search']}` search on a Dask cluster", "",
             (f"Command: `{out.get('command') or 'ftdrake study --paper'}`. The unreduced "
             "search (every feature set, all training rows, exhaustive, uncapped SVR): "
             f"`{FULL_PAPER_COMMAND}`."), "",
             f"Cluster: {out['workers']} workers at `{out['cluster']}`. Wall time "
             f"{out['wall_time_s']:.0f} s (collection {out['collect_s']:.0f} s); tuning: "
             + ", ".join(f"{k} {v:.0f} s" for k, v in res["tune_s"].items()) + ".", "",
             "## What this run did, and what it left out of the paper's grid search", "",
             f"* Training rows: {sizes['train_rows']} of the study trajectory's "
             f"{sizes['study_rows'] - sizes['test_rows']} training-split rows"
             + (" (all)." if not s["max_train_rows"] else
                f" (`--max-train-rows {s['max_train_rows']}`, drawn at random)."),
             (f"* Test rows: {sizes['test_rows']} random rows of the same trajectory (the "
             f"study's protocol); {sizes['heldout_rows']} rows of "
             f"{sizes['heldout_trajectories']} other trajectories (study_on_new)."),
             ("* Every candidate of the paper grid enters the search; 5 shuffled folds per "
             "candidate and round, each axis tuned on its own (as in the study).")]
    if s["search"] == "halving":
        lines += [
            (f"* Successive halving (scikit-learn `HalvingGridSearchCV`), factor {h['factor']}: "
            f"each round keeps the best 1/{h['factor']} of the candidates and gives them "
            f"{h['factor']}× the budget. Only the last round's survivors see the full budget: "
            "a candidate dropped early might have won with more (halving's gamble)."),
            "* RF budget: " + ("the tree count. The grid's `n_estimators` (100…2000) is the "
                               "resource, starting at 100 trees; the other parameters "
                               "(max_features × min_samples_leaf) are the candidates. Tree "
                               "counts between the rounds' budgets are not tried."
                               if h["rf_resource"] == "n_estimators" else
                               f"rows, from {h['min_rows']}.")
            + " Rounds and candidates per axis below.",
            (f"* SVR budget: rows, from {h['min_rows']}. libsvm stops after "
            f"{h['svr_max_iter']:,} iterations (the study's SVR has no cap; C = 1e5 poly/"
            "sigmoid fits do not converge and would run for many minutes each): such a fit "
            "scores what it reached.")]
    lines += ["", "## Exhaustive grid search, for comparison", "",
              "Fits (candidates × 5 folds × 6 axes): "
              + "; ".join(f"{m} {f}: {n:,}" for m, v in out["exhaustive_fits"].items()
                          for f, n in v.items())
              + "; this run fitted (candidates × rounds, per axis, × 5 folds): "
              + "; ".join(f"{k}: {sum(v.values()) * 5:,}"
                          for k, v in out["fitted_candidates"].items()) + "."]
    if "exhaustive_s_estimate" in out:
        lines.append("Estimated exhaustive time on these workers and these rows (scaled from "
                     "the last halving round's fit times; SVR a lower bound): "
                     + "; ".join(f"{k} {_hours(v)}" for k, v in
                                 out["exhaustive_s_estimate"].items()) + ".")
    lines += ["", "## Best parameters per axis", "",
              ("With the budget of each round (`n_resources`), the candidates fitted over all "
              "rounds, and the rounds' summed fit times (s)."), ""]
    for key, params in _flat_params(res["best_params"]["study"]).items():
        for a, p in params.items():
            shown = ", ".join(f"{k}={v}" for k, v in sorted(p.items())
                              if k not in ("n_resources", "round_fit_s", "resource",
                                           "n_candidates_fitted", "last_round_mean_fit_s"))
            extra = (f"; {p.get('resource')} {p.get('n_resources')}, "
                     f"{p.get('n_candidates_fitted')} candidates, rounds "
                     f"{p.get('round_fit_s')} s" if "n_resources" in p else "")
            lines.append(f"* {key} {a}: {shown}{extra}")
    return "\n".join([*lines, "", protocols_section]) + "\n"


def _hours(seconds: float) -> str:
    if seconds >= 3600:
        return f"~{seconds / 3600:.1f} h"
    return f"~{seconds / 60:.0f} min" if seconds >= 60 else f"~{seconds:.2g} s"


def _flat_params(best: dict) -> dict:
    return {f"{m} {f}": p for m, by_f in best.items() for f, p in by_f.items()}
