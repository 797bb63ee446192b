"""The contour experiment end to end at a tiny size: what it writes, and that a fixed seed
reproduces it to the last digit."""

import json

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from ftdrake.config.contour import HoleConfig
from ftdrake.experiments.contour import ContourPlan, plot_contours, run_contour_experiment


def _tiny(seed: int = 0) -> ContourPlan:
    # A Ø 4 mm hole at 50 mm/s: a 0.3 s run; GPs of 20 points.
    return ContourPlan(
        iterations=1,
        hole=HoleConfig(diameter_m=0.004, speed_m_s=0.05, rest_s=0.05),
        new_hole=HoleConfig(diameter_m=0.005, speed_m_s=0.05, rest_s=0.05,
                            offset_m=[0.002, 0.0, 0.0]),
        max_points=20, optimize_points=30).with_seed(seed)


def test_with_seed_seeds_every_noise_source():
    dut = ContourPlan().with_seed(7)
    assert (dut.seed, dut.tracker.seed, dut.contour_scan.seed) == (7, 7, 7)


def _drop_times(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k != "wall_time_s"}


def _colours_by_label(fig) -> dict:
    colours: dict = {}
    for ax in fig.axes:
        for line in ax.get_lines():
            colours.setdefault(line.get_label(), set()).add(matplotlib.colors.to_hex(
                line.get_color()))
    return colours


def test_figure_gives_each_method_one_colour_in_every_panel(tmp_path, monkeypatch):
    theta = np.linspace(0, 2 * np.pi, 50)
    circle = np.column_stack([np.cos(theta), np.sin(theta)])
    methods = ("torque", "timed", "contour", "ilc")
    np.savez(tmp_path / "contours.npz", task_radius=0.01, new_radius=0.013,
             **{f"{hole}_{m}": r * circle for hole, r in (("task", 0.0101), ("new", 0.0131))
                for m in ("none", *methods)})
    (tmp_path / "summary.json").write_text(json.dumps(
        {"task": {m: {"radial_rms_mm": [0.9, 0.1, 0.01]} for m in methods}}))
    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    plot_contours(tmp_path)
    colours = _colours_by_label(figures[0])
    assert set(colours) == {"ideal", "none", *methods}
    assert all(len(c) == 1 for c in colours.values()), colours
    assert len({next(iter(c)) for c in colours.values()}) == len(colours)
    assert (tmp_path / "contour.png").stat().st_size > 0


def test_contour_experiment_end_to_end_and_reproducible(tmp_path):
    stamp = {"command": "ftdrake learn-feedforward --two-part", "commit": "abc1234"}
    first = run_contour_experiment(plan=_tiny(3), out_dir=tmp_path / "a", progress=False,
                                   provenance=stamp)
    again = run_contour_experiment(plan=_tiny(3), out_dir=tmp_path / "b", progress=False,
                                   provenance=stamp)
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["provenance"] == stamp
    # Every figure the run wrote, to the last digit (the wall times aside).
    assert json.dumps(_drop_times(first)) == json.dumps(_drop_times(again))
    tables = [pd.read_csv(tmp_path / d / "iterations.csv").drop(columns=["wall_time_s", "fit_s"])
              for d in "ab"]
    pd.testing.assert_frame_equal(*tables, check_exact=True)
    with (np.load(tmp_path / "a" / "contours.npz") as a,
          np.load(tmp_path / "b" / "contours.npz") as b):
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key])
    assert (tmp_path / "a" / "contour.png").stat().st_size > 0
    # What the run measures: one row per method and iteration, and the new hole's.
    table = tables[0]
    assert len(table) == 1 + 4 * 1 + 5
    assert set(table.method) == {"none", "torque", "timed", "contour", "ilc"}
    # The encoders see less of the hole's error than the tool makes (the gearboxes' twist),
    # and every method learns something from one run.
    run0 = first["first_run"]
    assert 0.0 < run0["invisible_share"] <= 1.0
    assert run0["radial_motor_rms_mm"] < run0["radial_rms_mm"]
    for method, values in first["task"].items():
        assert values["radial_rms_mm"][1] < 0.8 * values["radial_rms_mm"][0], method
    # A different seed draws other tracker noise: the timed method's figures change.
    other = run_contour_experiment(plan=_tiny(4), progress=False)
    assert other["task"]["timed"]["radial_rms_mm"][1] != first["task"]["timed"]["radial_rms_mm"][1]
