"""The study's figures: per dataset, NMSE and MSE per axis, variance scores, importances.

Each maker in :data:`FIGURE_MAKERS` takes (pyplot, results, dataset) and returns a figure;
:func:`write_figures` writes every one for every dataset. Matplotlib draws with the Agg
backend (:mod:`ftdrake.plots`): no screen needed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...io import atomic_path
from ...plots import plt
from .layout import AXES, DATASETS, FEATURES, FIGURES
from .report import METHOD_LABELS

_COLORS = {"rf": ("#9ecae1", "#4292c6", "#08519c"), "svr": ("#fdae6b", "#f16913", "#a63603")}


def write_figures(results: dict, out_dir: Path) -> list[Path]:
    """The study's figures for every dataset: ``<figure>_<dataset>.png`` in `out_dir`."""
    paths = []
    for d in DATASETS:
        for name in FIGURES:
            fig = FIGURE_MAKERS[name](plt, results, d)
            path = Path(out_dir) / f"{name}_{d}.png"
            with atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=100, format="png")
            plt.close(fig)
            paths.append(path)
    return paths


def _bars(ax, results, d, metric, axes, log=False):
    """Grouped bars: per wrench axis, RF and SVR × the three feature sets."""
    width = 0.8 / (2 * len(FEATURES))
    x = np.arange(len(axes))
    for i, method in enumerate(("rf", "svr")):
        for k, f in enumerate(FEATURES):
            cell = results["metrics"][d][method][f]
            values = [cell[a][metric] for a in axes]
            offset = (i * len(FEATURES) + k - (2 * len(FEATURES) - 1) / 2) * width
            ax.bar(x + offset, values, width, color=_COLORS[method][k],
                   label=f"{METHOD_LABELS[method]} {f}")
    ax.set_xticks(x, axes)
    if log:
        ax.set_yscale("log")
    ax.grid(axis="y", alpha=0.3, which="both")


def _legend_right(ax):
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)


def _fig_nmse(plt, results, d):
    fig, ax = plt.subplots(figsize=(9, 4.2))
    _bars(ax, results, d, "nmse", AXES, log=True)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")  # NMSE 1: no better than the mean
    ax.set_ylabel("NMSE (MSE / var)  [1 = predicting the mean]")
    ax.set_title(f"NMSE per axis, held-out trajectories — {d}")
    _legend_right(ax)
    fig.tight_layout()
    return fig


def _fig_mse(plt, results, d):
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    _bars(left, results, d, "mse", AXES[:3], log=True)
    _bars(right, results, d, "mse", AXES[3:], log=True)
    left.set_ylabel("MSE [N²]")
    right.set_ylabel("MSE [(N·m)²]")
    _legend_right(right)
    fig.suptitle(f"MSE per axis, held-out trajectories — {d}")
    fig.tight_layout()
    return fig


def _fig_variance(axes, kind):
    def make(plt, results, d):
        fig, ax = plt.subplots(figsize=(8, 4.2))
        _bars(ax, results, d, "variance_score", axes)
        bottom = -1.0  # a worse-than-mean model is clipped here, its value written on it
        values = [results["metrics"][d][m][f][a]["variance_score"] for m in ("rf", "svr")
                  for f in FEATURES for a in axes]
        ax.set_ylim(max(min(0.0, min(values)) - 0.05, bottom), 1.02)
        for bar in ax.patches:
            if bar.get_height() < bottom:
                ax.text(bar.get_x() + bar.get_width() / 2, bottom + 0.02,
                        f"{bar.get_height():.1f}", rotation=90, ha="center", va="bottom",
                        fontsize=7, bbox={"facecolor": "w", "alpha": 0.8, "lw": 0, "pad": 1})
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylabel("variance score  [1 = perfect]")
        ax.set_title(f"Variance score of the {kind} models — {d}")
        _legend_right(ax)
        fig.tight_layout()
        return fig

    return make


def _fig_importances(plt, results, d):
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6))
    block_color = {"q": "#08519c", "qd": "#6baed6", "qdd": "#c6dbef"}
    for ax, f in ((top, "q,qd,qdd"), (bottom, "q")):
        imp = results["feature_importances"][d][f]
        names = list(imp)
        ax.bar(range(len(names)), list(imp.values()),
               color=[block_color[n.rsplit("_", 1)[0]] for n in names])
        ax.set_xticks(range(len(names)), names, rotation=90 if len(names) > 7 else 0,
                      fontsize=8)
        ax.set_ylabel("importance")
        ax.set_title(f"Fx random forest on {f}", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in block_color.values()]
    top.legend(handles, ["q (rad)", "q̇ (rad/s)", "q̈ (rad/s²)"], fontsize=8, loc="upper right")
    fig.suptitle(f"Feature importances of the Fx RF model — {d}")
    fig.tight_layout()
    return fig


FIGURE_MAKERS = {"nmse": _fig_nmse, "mse": _fig_mse,
                  "variance_forces": _fig_variance(AXES[:3], "force"),
                  "variance_torques": _fig_variance(AXES[3:], "torque"),
                  "importances": _fig_importances}
