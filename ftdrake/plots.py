"""Figures. Matplotlib with the Agg backend: no screen needed."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import columns as col  # noqa: E402


def shade_contact(ax, t, contact, label="true contact"):
    """Shades the intervals where `contact` is 1."""
    contact = np.asarray(contact).astype(bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], contact.astype(int), [0]])))
    for k, (a, b) in enumerate(zip(edges[::2], edges[1::2])):
        ax.axvspan(t[a], t[b - 1], color="tab:red", alpha=0.12, lw=0,
                   label=label if k == 0 else None)


def plot_wrench_log(log, path: Path, title: str = "F/T sensor") -> None:
    """Measured vs true internal wrench per axis, true contact shaded."""
    fig, axes = plt.subplots(6, 1, figsize=(10, 11), sharex=True)
    t = log[col.TIME].to_numpy()
    for ax, axis, unit in zip(axes, col.WRENCH_AXES, col.WRENCH_UNITS):
        ax.plot(t, log[f"{col.MEASURED}_{axis}"], lw=0.6, color="0.4", label="measured")
        ax.plot(t, log[f"{col.INTERNAL}_{axis}"], lw=1.0, color="tab:blue",
                label="true internal (no contact)")
        ax.plot(t, log[f"{col.EXTERNAL}_{axis}"], lw=1.0, color="tab:red",
                label="true external (contact)")
        shade_contact(ax, t, log[col.CONTACT])
        ax.set_ylabel(f"{axis} [{unit}]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=4)
    axes[0].set_title(f"{title} — sensor frame S")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
