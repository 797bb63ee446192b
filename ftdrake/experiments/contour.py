"""The hole-cutting benchmark with compliant joints: the two-part learned compensation.

:func:`run_contour_experiment` cuts a hole (:class:`~ftdrake.config.contour.HoleConfig`)
with compliant transmissions and joint friction on (the controller reads the motor angles
and knows neither the friction nor the true tool), then, from the same first run, learns for
``iterations`` runs with each method:

* ``torque``: part one only, the torque feedforward GP on the motor-side tracking
  (:mod:`ftdrake.systems.learned_feedforward`, data from every run so far);
* ``timed``: two-part, part one plus the reference correction
  (:mod:`ftdrake.experiments.reference_correction`) learned from a timed tool measurement;
* ``contour``: two-part with the reference correction learned from an untimed contour scan of
  the hole;
* ``ilc``: time-indexed ILC of the motor reference from the timed measurement (the paper's
  baseline), ``u_{k+1} = Q(u_k + γ J⁺ e_tool)``.

Then each method's final correction runs on a second hole (another diameter and position)
without relearning, beside a run without correction.

Per run: the hole's radial error (distance of the tool tip from the hole's centre in the plane
minus the radius, over the one full turn; RMS and max, mm); the same for the tip where the
*motor* angles would put it (what the encoders can see); the motor-side joint tracking RMS.
"""

from __future__ import annotations

import dataclasses as dc
import json
import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .. import conventions as col
from ..config import ScenarioConfig
from ..config.contour import ContourScanConfig, HoleConfig, TrackerConfig
from ..control.ilc import q_filter
from ..errors import ConfigError
from ..io import atomic_path, atomic_write_text
from ..sim.scene import make_control_plant
from ..sim.simulate import simulate
from ..sim.station import build_station, robot_geometry
from ..sim.tool_measurement import measure_contour, measure_timed, normal_deviation, timed_error
from ..systems.learned_feedforward import LearnedFeedforward, fit_feedforward_gp
from ..version import result_provenance
from .hole_path import Circle, HolePath, hole_trajectory
from .reference_correction import (
    ReferenceCorrection,
    corrected_reference,
    desired_states,
    tip_jacobian_pinv,
)
from .tool_files import register_simulated_scan, register_simulated_timed
from .two_part_model import TwoPartModel

logger = logging.getLogger(__name__)

METHODS = ("torque", "timed", "contour", "ilc")


@dc.dataclass
class ContourPlan:
    """What :func:`run_contour_experiment` runs."""

    iterations: int = 5
    hole: HoleConfig = dc.field(default_factory=lambda: HoleConfig(diameter_m=0.020))
    # The hole the final corrections run on without relearning: wider, centre moved.
    new_hole: HoleConfig = dc.field(default_factory=lambda: HoleConfig(
        diameter_m=0.026, offset_m=[0.004, -0.003, 0.0]))
    tracker: TrackerConfig = dc.field(default_factory=TrackerConfig)
    contour_scan: ContourScanConfig = dc.field(default_factory=ContourScanConfig)
    methods: tuple = METHODS
    reference_gain: float = 1.0  # γ of the incremental reference updates (ILC, "tool")
    # What part two learns. "transmission" (the paper's split): what the encoders cannot
    # see, the tool's offset from where the motor angles put it, ``J⁺ (p(φ) − p_measured)``
    # (timed) or the same along the path's normal (contour); part one handles the rest.
    # "tool": the whole tool error, incrementally, ``c + γ J⁺ (p_desired − p_measured)``.
    reference_target: str = "transmission"
    max_points: int = 200  # GP subset size per joint (both parts)
    optimize_points: int = 300
    trust_ratio: float = 0.5
    reject_ratio: float = 0.9
    ilc_cutoff_hz: float = 5.0
    # The GP's reference offsets are low-passed (zero-phase) at this cut-off before the
    # reference is splined: where the confidence rule ramps the correction in or out (the
    # contour data cover only the hole) the offset would otherwise change in a few ms, and
    # the controller's feedforward of its second derivative would kick the motors.
    reference_cutoff_hz: float = 5.0
    seed: int = 0  # the GP fits' (see :meth:`with_seed` for every noise source)

    def with_seed(self, seed: int) -> ContourPlan:
        """This plan with `seed` for every source of randomness: the GP fits, the tracker's
        noise and the contour scan's noise (the simulation itself draws none: the F/T sensor
        is ideal in this benchmark)."""
        return dc.replace(self, seed=int(seed),
                          tracker=dc.replace(self.tracker, seed=int(seed)),
                          contour_scan=dc.replace(self.contour_scan, seed=int(seed)))

    def validate(self) -> ContourPlan:
        if self.iterations < 1:
            raise ConfigError(f"--iterations: must be >= 1, got {self.iterations}")
        if self.reference_target not in ("transmission", "tool"):
            raise ConfigError(f"reference_target: 'transmission' or 'tool', got "
                              f"{self.reference_target!r}")
        unknown = set(self.methods) - set(METHODS)
        if unknown:
            raise ConfigError(f"methods: unknown {sorted(unknown)}; choose from {METHODS}")
        if not self.reference_gain > 0:
            raise ConfigError(f"reference_gain: must be > 0, got {self.reference_gain}")
        self.hole.validate("hole")
        self.new_hole.validate("new_hole")
        self.tracker.validate("tracker")
        self.contour_scan.validate("contour_scan")
        return self


def contour_scenario(config: ScenarioConfig) -> ScenarioConfig:
    """`config` with compliant transmissions and friction on and an ideal F/T sensor (it plays
    no part in tracking)."""
    return dc.replace(
        config, transmission=dc.replace(config.transmission, enabled=True),
        friction=dc.replace(config.friction, enabled=True),
        sensor=dc.replace(config.sensor, imperfections=False)).validate()


@dc.dataclass
class Task:
    """One hole: its ideal path, the joint trajectory, and what learning needs per log row."""

    path: HolePath
    trajectory: object  # PiecewisePolynomial q_d(t)
    t: np.ndarray = None  # the log's times (filled by the first run)
    X_d: np.ndarray = None  # [q_d, q̇_d, q̈_d] at t
    J_pinv: np.ndarray = None  # (N, n, 3)


class HoleRunner:
    """Runs a hole with given corrections and measures the contour."""

    def __init__(self, config: ScenarioConfig):
        self.config = config
        self.geometry = robot_geometry(config)
        self.plant = self.geometry.plant
        self.arm = self.geometry.arm
        self.scene = self.geometry._scene
        self.tip_frame = self.scene.tool_tip_frame()
        self._context = self.plant.CreateDefaultContext()
        self.control_plant = make_control_plant(config, self.scene)
        self._control_context = self.control_plant.CreateDefaultContext()
        self.n = self.plant.num_positions(self.arm)
        q_home = np.asarray(config.home_q, dtype=float)
        self.p_home = self.geometry.tip_and_axis(q_home)[0]

    def task(self, hole: HoleConfig) -> Task:
        path = HolePath.from_config(hole, self.p_home)
        return Task(path, hole_trajectory(path, self.geometry, self.config.home_q))

    def tips(self, Q) -> np.ndarray:
        out = np.empty((len(Q), 3))
        for i, q in enumerate(Q):
            self.plant.SetPositions(self._context, self.arm, q)
            out[i] = self.tip_frame.CalcPoseInWorld(self._context).translation()
        return out

    def mass_times(self, Q, W) -> np.ndarray:
        plant, context = self.control_plant, self._control_context
        out = np.empty_like(Q)
        for i in range(len(Q)):
            plant.SetPositions(context, Q[i])
            out[i] = plant.CalcMassMatrix(context) @ W[i]
        return out

    def run(self, task: Task, reference=None, feedforward=None) -> dict:
        reference = task.trajectory if reference is None else reference
        station = build_station(self.config, trajectory=reference, feedforward=feedforward)
        result = simulate(station, progress=False, duration=task.path.duration)
        log = result.log
        n = self.n
        t = log[col.TIME].to_numpy()
        q = log[col.joint_columns(col.Q, n)].to_numpy()
        motor = _motor_rows(station, result.context, t)
        phi, omega = motor[:, :n], motor[:, n:]
        if task.t is None or len(task.t) != len(t) or not np.allclose(task.t, t):
            task.t = t
            task.X_d = desired_states(task.trajectory, t)
            task.J_pinv = tip_jacobian_pinv(self.plant, self.arm, self.tip_frame,
                                            task.X_d[:, :n])
        p_link, p_motor = self.tips(q), self.tips(phi)
        p_d = task.path.position_W(t)
        on_hole = task.path.hole_mask(t)
        radial = task.path.radial_error(p_link[on_hole])
        radial_motor = task.path.radial_error(p_motor[on_hole])
        applied = np.zeros_like(q)
        if station.feedforward_log is not None:
            ff = station.feedforward_log.FindLog(result.context)
            keep = ff.sample_times() > 0.5 * self.config.time_step
            applied = ff.data().T[keep][:, :n]
        # Part one's target on the motor side: τ − ID̂(φ, φ̇, φ̈), what the model lacked.
        X_ref = desired_states(reference, t)
        a_motor = np.gradient(omega, t, axis=0)
        c = self.config.controller
        e, de = X_ref[:, :n] - phi, X_ref[:, n:2 * n] - omega
        model_error = applied + self.mass_times(phi, c.kp * e + c.kd * de + X_ref[:, 2 * n:]
                                                - a_motor)
        tool = p_link - p_d
        invisible = p_link - p_motor
        return {
            "t": t, "p_link": p_link, "p_motor": p_motor, "on_hole": on_hole,
            "X_motor": np.hstack([phi, omega, a_motor]), "model_error": model_error,
            "radial_rms_mm": float(1e3 * np.sqrt(np.mean(radial**2))),
            "radial_max_mm": float(1e3 * np.abs(radial).max()),
            "radial_motor_rms_mm": float(1e3 * np.sqrt(np.mean(radial_motor**2))),
            "tool_rms_mm": float(1e3 * np.sqrt((tool[on_hole]**2).sum(1).mean())),
            "invisible_rms_mm": float(1e3 * np.sqrt((invisible[on_hole]**2).sum(1).mean())),
            "motor_rms_mrad": float(1e3 * np.sqrt((e**2).sum(1).mean())),
            "contour_P": task.path.to_plane(p_link[on_hole]),
            "contour_motor_P": task.path.to_plane(p_motor[on_hole]),
            "wall_time_s": float(result.timing["wall_time_s"]),
        }


def _motor_rows(station, context, t) -> np.ndarray:
    """The motors' [φ, φ̇] at the log's times (the motor logger samples at t = 0 too)."""
    log = station.motor_state_log.FindLog(context)
    times, data = log.sample_times(), log.data().T
    index = np.searchsorted(times, t - 1e-9)
    return data[np.clip(index, 0, len(times) - 1)]


def tool_error_joint(task: Task, run: dict, measurement: str, plan: ContourPlan,
                     target: str = "tool"):
    """(rows, Δq): the log rows where the tool error is known and the error mapped to the
    joints there, ``J⁺ e`` (rad). `target` "tool": ``e = p_desired − p_measured``;
    "transmission": ``e = p(φ) − p_measured``, the part the motor angles φ do not show.
    The contour gives only the component along the ideal path's normal."""
    t, path = run["t"], task.path
    if measurement == "timed":
        stamp, measured = measure_timed(t, run["p_link"], plan.tracker)
        stamp, measured, _ = register_simulated_timed(stamp, measured, t, run["p_motor"],
                                                      plan.tracker)
        if not plan.tracker.stamp_corrected:
            stamp = stamp - plan.tracker.latency_s  # a known latency is taken off
        rows = np.flatnonzero((t >= stamp[0]) & (t <= stamp[-1]))
        reference = (path.position_W(t[rows]) if target == "tool"
                     else run["p_motor"][rows])
        error_W = timed_error(t[rows], reference, stamp, measured)
    elif measurement == "contour":
        scan = measure_contour(run["contour_P"], plan.contour_scan)
        rows = np.flatnonzero(run["on_hole"])
        ideal = path.to_plane(path.position_W(t[rows]))
        scan, _ = register_simulated_scan(scan, ideal, plan.contour_scan)
        normal = (ideal / np.linalg.norm(ideal, axis=1, keepdims=True)
                  if isinstance(path.outline, Circle) else path.normal_P(t[rows]))
        deviation = normal_deviation(ideal, normal, scan)
        if target == "transmission":  # less what the motor angles' own path shows
            deviation = deviation - normal_deviation(ideal, normal, run["contour_motor_P"])
        keep = np.isfinite(deviation)
        rows, normal, deviation = rows[keep], normal[keep], deviation[keep]
        # The tool must move back along the normal by the deviation.
        error_W = (-deviation[:, None] * np.column_stack([normal, np.zeros(len(normal))])
                   @ path.R_WP.T)
    else:
        raise ConfigError(f"measurement: 'timed' or 'contour', got {measurement!r}")
    return rows, np.einsum("nij,nj->ni", task.J_pinv[rows], error_W)


def _fit(X, y, plan: ContourPlan, seed: int):
    return fit_feedforward_gp(X, y, max_points=plan.max_points,
                              optimize_points=plan.optimize_points, random_state=seed)


class Learner:
    """One method's corrections and how it updates them from a run."""

    def __init__(self, method: str, runner: HoleRunner, task: Task, plan: ContourPlan):
        self.method, self.runner, self.task, self.plan = method, runner, task, plan
        self.torque_data: list = []
        self.torque_model = self.reference_model = None
        self.ilc_u = None  # (N, n) on the task's log grid
        self.applied_reference = None  # the reference offsets used in the last run (N, n)
        self.fit_s = 0.0

    def feedforward(self):
        if self.torque_model is None:
            return None
        return LearnedFeedforward(self.torque_model, n_joints=self.runner.n,
                                  trust_ratio=self.plan.trust_ratio,
                                  reject_ratio=self.plan.reject_ratio)

    def reference(self, task: Task):
        """The corrected reference for `task` (the learned task or another hole)."""
        if self.method == "ilc" and self.ilc_u is not None:
            grid, u = self.task.t, self.ilc_u  # time-indexed: replayed at the same times

            def offset(t):
                return np.column_stack([np.interp(t, grid, u[:, j], left=0.0, right=0.0)
                                        for j in range(u.shape[1])])
            return corrected_reference(task.trajectory, offset)
        if self.reference_model is not None:
            correction = ReferenceCorrection(self.reference_model,
                                             trust_ratio=self.plan.trust_ratio,
                                             reject_ratio=self.plan.reject_ratio)

            cutoff = self.plan.reference_cutoff_hz

            def offset(t):
                c = correction.evaluate(desired_states(task.trajectory, t))[0]
                return q_filter(c, float(t[1] - t[0]), cutoff) if cutoff > 0 else c
            return corrected_reference(task.trajectory, offset)
        return None

    def update(self, run: dict, k: int) -> None:
        t0 = time.perf_counter()
        plan, task = self.plan, self.task
        if self.method in ("torque", "timed", "contour"):  # part one, from every run so far
            self.torque_data.append((run["X_motor"], run["model_error"]))
            self.torque_model = _fit(np.vstack([d[0] for d in self.torque_data]),
                                     np.vstack([d[1] for d in self.torque_data]), plan,
                                     plan.seed + k)
        if self.method in ("timed", "contour", "ilc"):  # part two, from this run's tool
            measurement = "contour" if self.method == "contour" else "timed"
            target = "tool" if self.method == "ilc" else plan.reference_target
            rows, dq = tool_error_joint(task, run, measurement, plan, target)
            applied = (self.applied_reference if self.applied_reference is not None
                       else np.zeros((len(task.t), self.runner.n)))
            if self.method == "ilc":
                full = np.zeros_like(applied)
                full[rows] = dq
                self.ilc_u = q_filter(applied + plan.reference_gain * full,
                                      float(np.median(np.diff(task.t))), plan.ilc_cutoff_hz)
            else:  # the transmission error is measured whole; the tool error incrementally
                y = dq if target == "transmission" else applied[rows] + plan.reference_gain * dq
                self.reference_model = _fit(task.X_d[rows], y, plan, plan.seed + 100 + k)
        self.fit_s = time.perf_counter() - t0

    def record_applied(self, reference) -> None:
        """Keeps the offsets the next run applies on the task's grid (q_ref − q_d)."""
        t = self.task.t
        self.applied_reference = (np.zeros((len(t), self.runner.n)) if reference is None else
                                  (reference.vector_values(t) - self.task.trajectory
                                   .vector_values(t)).T)


def _row(method, iteration, run, fit_s=0.0, hole="task"):
    return {"hole": hole, "method": method, "iteration": iteration,
            **{k: run[k] for k in ("radial_rms_mm", "radial_max_mm", "radial_motor_rms_mm",
                                   "tool_rms_mm", "invisible_rms_mm", "motor_rms_mrad",
                                   "wall_time_s")},
            "fit_s": fit_s}


def run_contour_experiment(config: ScenarioConfig | None = None,
                           plan: ContourPlan | None = None, out_dir=None, *,
                           progress: bool = True, model_out=None,
                           provenance: dict | None = None) -> dict:
    """Runs the benchmark; writes ``summary.json``, ``iterations.csv`` and ``contour.png``
    to `out_dir` when given, and with `model_out` the learned two-part model (the timed
    method's, else the contour one's; :mod:`ftdrake.experiments.two_part_model`). Returns
    the summary (with `provenance`, e.g. the command and commit that ran it, under
    ``"provenance"`` when given; else the written summary records this process's)."""
    plan = (plan or ContourPlan()).validate()
    if model_out is not None and not {"timed", "contour"} & set(plan.methods):
        raise ConfigError("model_out: needs a two-part method ('timed' or 'contour') in "
                          f"methods, got {list(plan.methods)}")
    scenario = contour_scenario(config or ScenarioConfig())
    start = time.perf_counter()
    runner = HoleRunner(scenario)
    task = runner.task(plan.hole)
    first = runner.run(task)
    rows = [_row("none", 0, first)]
    contours = {"none": first["contour_P"]}
    learners = {}
    for method in plan.methods:
        learner = learners[method] = Learner(method, runner, task, plan)
        learner.record_applied(None)
        last = first
        for k in range(1, plan.iterations + 1):
            learner.update(last, k)
            reference = learner.reference(task)
            learner.record_applied(reference)
            last = runner.run(task, reference, learner.feedforward())
            rows.append(_row(method, k, last, learner.fit_s))
            if progress:
                logger.warning("%s %d: radial RMS %.4f mm", method, k, last["radial_rms_mm"])
        contours[method] = last["contour_P"]
    if model_out is not None:
        _save_two_part(learners, plan, model_out)

    new_task = runner.task(plan.new_hole)
    new_runs = {"none": runner.run(new_task)}
    rows.append(_row("none", plan.iterations, new_runs["none"], hole="new"))
    for method, learner in learners.items():
        new_runs[method] = runner.run(new_task, learner.reference(new_task),
                                      learner.feedforward())
        rows.append(_row(method, plan.iterations, new_runs[method], hole="new"))
    table = pd.DataFrame(rows)
    summary = _summary(table, plan, first, time.perf_counter() - start)
    if provenance is not None:
        summary["provenance"] = dict(provenance)
    if out_dir is not None:
        write_outputs(Path(out_dir), table, summary, task, contours, new_task,
                      {k: v["contour_P"] for k, v in new_runs.items()})
    return summary


def _save_two_part(learners: dict, plan: ContourPlan, path) -> None:
    method = "timed" if "timed" in learners else "contour"
    TwoPartModel.from_learner(learners[method], info={
        "hole": dc.asdict(plan.hole), "iterations": plan.iterations,
        "reference_target": plan.reference_target}).save(path)


def _summary(table: pd.DataFrame, plan: ContourPlan, first: dict, wall: float) -> dict:
    task = table[table.hole == "task"]
    none = float(first["radial_rms_mm"])
    per_method = {}
    for method in plan.methods:
        rms = [none, *task[task.method == method].radial_rms_mm.astype(float)]
        mx = [float(first["radial_max_mm"]),
              *task[task.method == method].radial_max_mm.astype(float)]
        per_method[method] = {"radial_rms_mm": rms, "radial_max_mm": mx,
                              "best_within_5": min(rms[:6]), "last": rms[-1]}
    new = table[table.hole == "new"].set_index("method")
    new_none = float(new.loc["none", "radial_rms_mm"])
    generalisation = {m: {"radial_rms_mm": float(new.loc[m, "radial_rms_mm"]),
                          "radial_max_mm": float(new.loc[m, "radial_max_mm"]),
                          "improvement": new_none / float(new.loc[m, "radial_rms_mm"])}
                      for m in new.index}
    goals = {}
    if {"timed", "torque"} <= set(plan.methods):
        timed = per_method["timed"]["best_within_5"]
        goals["timed_10x_below_none"] = none / timed >= 10
        goals["timed_3x_below_torque_only"] = per_method["torque"]["best_within_5"] / timed >= 3
        if "contour" in plan.methods:
            goals["contour_within_2x_of_timed"] = (
                per_method["contour"]["best_within_5"] / timed <= 2)
        goals["timed_keeps_3x_on_new_hole"] = generalisation["timed"]["improvement"] >= 3
    if "ilc" in plan.methods:
        goals["ilc_does_not_keep_3x_on_new_hole"] = generalisation["ilc"]["improvement"] < 3
    return {
        "plan": json.loads(json.dumps(dc.asdict(plan), default=list)),
        "first_run": {
            "radial_rms_mm": none, "radial_max_mm": float(first["radial_max_mm"]),
            "radial_motor_rms_mm": float(first["radial_motor_rms_mm"]),
            "tool_rms_mm": float(first["tool_rms_mm"]),
            "invisible_rms_mm": float(first["invisible_rms_mm"]),
            # The share of the tool's error the encoders cannot see (RMS ratio, 3-D).
            "invisible_share": float(first["invisible_rms_mm"] / first["tool_rms_mm"]),
        },
        "task": per_method,
        "generalisation": generalisation,
        "goals": goals,
        "wall_time_s": wall,
    }


#: One colour per method in every panel of the figure (the ideal contour: black, dashed).
METHOD_COLOURS = {"none": "tab:gray", "torque": "tab:blue", "timed": "tab:orange",
                  "contour": "tab:green", "ilc": "tab:red"}


def write_outputs(out: Path, table, summary, task, contours, new_task, new_contours) -> None:
    """summary.json, iterations.csv, contours.npz (each method's final contour, in-plane m)
    and contour.png (:func:`plot_contours`), each atomically."""
    out.mkdir(parents=True, exist_ok=True)
    summary = {**summary, "provenance": summary.get("provenance") or result_provenance()}
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    with atomic_path(out / "iterations.csv") as tmp:
        table.to_csv(tmp, index=False)
    with atomic_path(out / "contours.npz") as tmp, open(tmp, "wb") as f:
        np.savez(f, **{f"task_{k}": v for k, v in contours.items()},
                 **{f"new_{k}": v for k, v in new_contours.items()},
                 task_radius=task.path.radius, new_radius=new_task.path.radius)
    plot_contours(out)


def plot_contours(out: Path) -> Path:
    """Draws ``out/contour.png`` from ``out/contours.npz`` and ``out/summary.json`` (so a
    run's figure can be redrawn from its files): per hole, the contours against the ideal
    circle at true scale and the radial error along the hole; the radial RMS per iteration.
    Each method has one colour in every panel (:data:`METHOD_COLOURS`)."""
    import matplotlib  # noqa: PLC0415 (only when writing the figure)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    out = Path(out)
    summary = json.loads((out / "summary.json").read_text())
    with np.load(out / "contours.npz") as data:
        files = {k: data[k] for k in data.files}
    fig, axes = plt.subplots(2, 3, figsize=(15, 9))
    for col_, (prefix, title) in enumerate((("task", "learned hole"),
                                            ("new", "new hole, no relearning"))):
        ax, ax_err = axes[0, col_], axes[1, col_]
        radius = float(files[f"{prefix}_radius"])
        theta = np.linspace(0, 2 * np.pi, 400)
        ax.plot(1e3 * radius * np.cos(theta), 1e3 * radius * np.sin(theta), "k--",
                lw=1.5, label="ideal")
        names = [k[len(prefix) + 1:] for k in files if k.startswith(prefix + "_")
                 and k != f"{prefix}_radius"]
        for name in names:
            p, colour = files[f"{prefix}_{name}"], METHOD_COLOURS.get(name)
            ax.plot(1e3 * p[:, 0], 1e3 * p[:, 1], lw=1, label=name, color=colour)
            angle = np.degrees(np.unwrap(np.arctan2(p[:, 1], p[:, 0])))
            ax_err.semilogy(angle - angle[0], 1e3 * np.abs(np.linalg.norm(p, axis=1) - radius),
                            lw=1, label=name, color=colour)
        ax.set_aspect("equal")
        ax.set_title(f"{title} (Ø {2e3 * radius:g} mm), true scale")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.legend(fontsize=8)
        ax_err.set_xlabel("angle along the hole (°)")
        ax_err.set_ylabel("|radial error| (mm)")
        ax_err.set_title(f"{title}: radial error")
        ax_err.legend(fontsize=8)
    ax = axes[0, 2]
    for method, values in summary["task"].items():
        ax.semilogy(range(len(values["radial_rms_mm"])), values["radial_rms_mm"], "o-",
                    label=method, color=METHOD_COLOURS.get(method))
    ax.set_xlabel("iteration")
    ax.set_ylabel("radial RMS error (mm)")
    ax.set_title("learned hole")
    ax.legend()
    axes[1, 2].axis("off")
    fig.tight_layout()
    with atomic_path(out / "contour.png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return out / "contour.png"


__all__ = ["ContourPlan", "HoleRunner", "plot_contours", "run_contour_experiment",
           "tool_error_joint"]
