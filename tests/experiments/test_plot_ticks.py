"""The detectable-force figure's tick labels do not overlap (its axes span less than a decade
or two, where matplotlib labels every minor tick ``3×10⁻¹``, ``4×10⁻¹``), and they are plain
numbers at the ticks' values."""

import itertools
import json

import numpy as np
import pytest

from ftdrake.experiments.detection_domain import detectable_force_figure
from ftdrake.plots import plt
from tests.helpers import ROOT


def visible_labels(axis, renderer):
    """(text, value, bounding box) of each labelled tick inside the axis' view."""
    low, high = sorted(axis.get_view_interval())
    out = []
    for tick in [*axis.get_major_ticks(), *axis.get_minor_ticks()]:
        text = tick.label1
        if text.get_visible() and text.get_text() and low <= tick.get_loc() <= high:
            out.append((text.get_text(), tick.get_loc(), text.get_window_extent(renderer)))
    return out


@pytest.fixture
def figure():
    results = json.loads((ROOT / "docs" / "detection" / "detection.json").read_text())["models"]
    fig = detectable_force_figure(results)
    assert fig is not None
    fig.canvas.draw()
    yield fig
    plt.close(fig)


def test_tick_labels_do_not_overlap_and_read_as_numbers(figure):
    renderer = figure.canvas.get_renderer()
    ax = figure.axes[0]
    for axis in (ax.xaxis, ax.yaxis):
        labels = sorted(visible_labels(axis, renderer), key=lambda x: x[1])
        assert len(labels) >= 2, labels
        for (_, _, a), (_, _, b) in itertools.pairwise(labels):
            assert not a.overlaps(b), [x[0] for x in labels]
        for text, value, _ in labels:  # plain numbers, equal to the tick's value
            assert float(text) == pytest.approx(value, rel=1e-6), text
    assert np.isclose(min(v for _, v, _ in visible_labels(ax.xaxis, renderer)), 0.2)
