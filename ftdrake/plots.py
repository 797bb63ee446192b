"""Figures. Matplotlib with the Agg backend: no screen needed.

Modules that draw figures of their own take ``plt`` (pyplot, Agg selected) from here.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from . import conventions as col


def shade_contact(ax, t, contact, label="true contact"):
    """Shades the intervals where `contact` is 1."""
    contact = np.asarray(contact).astype(bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], contact.astype(int), [0]])))
    for k, (a, b) in enumerate(zip(edges[::2], edges[1::2], strict=True)):
        ax.axvspan(t[a], t[b - 1], color="tab:red", alpha=0.12, lw=0,
                   label=label if k == 0 else None)


def plot_wrench_log(log, path: Path, title: str = "F/T sensor") -> None:
    """Measured vs true internal wrench per axis, true contact shaded."""
    fig, axes = plt.subplots(6, 1, figsize=(10, 11), sharex=True)
    t = log[col.TIME].to_numpy()
    for ax, axis, unit in zip(axes, col.WRENCH_AXES, col.WRENCH_UNITS, strict=True):
        ax.plot(t, log[f"{col.MEASURED}_{axis}"], lw=0.6, color="0.4", label="measured")
        ax.plot(t, log[f"{col.INTERNAL_TRUE}_{axis}"], lw=1.0, color="tab:blue",
                label="true internal (no contact)")
        ax.plot(t, log[f"{col.EXTERNAL_TRUE}_{axis}"], lw=1.0, color="tab:red",
                label="true external (contact)")
        shade_contact(ax, t, log[col.CONTACT_TRUE])
        ax.set_ylabel(f"{axis} [{unit}]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=4)
    axes[0].set_title(f"{title} — sensor frame S")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_contact_comparison(logs: dict, path: Path,
                            title: str = "contact scenario, each model in the loop"):
    """One column per model (``logs``: name → closed-loop log): raw vs compensated Fx, Fy, Fz,
    the true external force, and true vs detected contact; the same axes limits throughout."""
    names = list(logs)
    fig, axes = plt.subplots(4, len(names), figsize=(6 * len(names), 9), sharex=True,
                             sharey="row", squeeze=False,
                             gridspec_kw={"height_ratios": [3, 3, 3, 1]})
    for c, name in enumerate(names):
        log = logs[name]
        t = log[col.TIME].to_numpy()
        for r, axis in enumerate(("Fx", "Fy", "Fz")):
            ax = axes[r, c]
            ax.plot(t, log[f"{col.MEASURED}_{axis}"], lw=0.7, color="0.55", label="measured (raw)")
            ax.plot(t, log[f"{col.WRENCH_CONTACT}_{axis}"], lw=0.8, color="tab:blue",
                    label="compensated (estimated external)")
            ax.plot(t, log[f"{col.EXTERNAL_TRUE}_{axis}"], lw=1.0, color="tab:red", ls="--",
                    label="true external")
            shade_contact(ax, t, log[col.CONTACT_TRUE])
            ax.grid(alpha=0.3)
            if c == 0:
                ax.set_ylabel(f"{axis} [N]")
        axes[0, c].set_title(name)
        shade_contact(axes[3, c], t, log[col.CONTACT_TRUE])
        axes[3, c].step(t, log[col.CONTACT], where="post", color="k", lw=1.0, label="detected")
        axes[3, c].set_yticks([0, 1])
        axes[3, c].set_xlabel("time [s]")
    axes[0, 0].legend(loc="lower left", fontsize=8)
    axes[3, 0].set_ylabel("contact")
    axes[3, 0].legend(loc="upper left", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
