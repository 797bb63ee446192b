"""Iterative learning of the torque feedforward (the seed paper's system), with ILC beside it.

:func:`run_feedforward_experiment` runs the task trajectory with joint friction on (the
controller's model knows neither it nor the true tool), then ``iterations`` times: fit the
learned feedforward on the last run, run again with it. The classic time-indexed ILC runs the
same task for the same number of iterations from the same first run. Then both final
corrections run on a *different* trajectory — the task's path at ``generalisation_speed`` of
its speed (the same poses, other velocities and accelerations; inside the learned region) —
beside a run without correction.

Per run: joint tracking RMS (mrad, of ‖q_d − q‖ over the joints) and tool-tip RMS (mm, of
the distance between the tool tip at q_d and at q, by the plant's kinematics), per joint RMS,
and for the GP the share of samples whose correction was scaled down.
"""

from __future__ import annotations

import dataclasses as dc
import json
import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd
from pydrake.trajectories import PiecewisePolynomial
from tqdm.auto import tqdm

from .. import conventions as col
from ..compensation.files.persistence import save_model
from ..config import ScenarioConfig
from ..control.ilc import ilc_update
from ..errors import ConfigError
from ..io import atomic_path, atomic_write_text
from ..plots import plt
from ..sim.scene import make_control_plant
from ..sim.simulate import simulate
from ..sim.station import build_station
from ..systems.learned_feedforward import LearnedFeedforward, fit_feedforward_gp
from ..systems.time_indexed_feedforward import TimeIndexedFeedforward
from ..version import result_provenance

logger = logging.getLogger(__name__)


@dc.dataclass
class FeedforwardPlan:
    """What :func:`run_feedforward_experiment` runs."""

    iterations: int = 5
    trajectory: str = "rehearsal"  # the task: TrajectoryConfig.kind
    seed: int = 0
    duration_s: float | None = None  # None: the scenario's trajectory.duration_s
    # The new trajectory: the task's path, time-scaled to this fraction of its speed.
    generalisation_speed: float = 0.8
    # What the GP learns. "model_error": τ − ID̂(q, q̇, q̈) at the state the arm was in,
    # ``c + M̂ (kp e + kd ė + q̈_d − q̈)``, from every run so far (a fixed function of the
    # state, so the runs agree). "feedback": ``c + τ_fb`` at the desired state, last run
    # only (plain feedback-error learning). ILC uses the same signal indexed by time.
    target: str = "model_error"
    max_points: int = 200  # GP subset size (m) per joint
    optimize_points: int = 300  # rows the GP's hyperparameters are fitted on
    trust_ratio: float = 0.5
    reject_ratio: float = 0.9
    ilc_gain: float = 1.0  # γ
    ilc_cutoff_hz: float = 5.0  # Q-filter

    def validate(self) -> FeedforwardPlan:
        if self.target not in ("model_error", "feedback"):
            raise ConfigError(f"target: 'model_error' or 'feedback', got {self.target!r}")
        if self.iterations < 1:
            raise ConfigError(f"--iterations: must be >= 1, got {self.iterations}")
        if not self.ilc_cutoff_hz > 0 or not self.ilc_gain > 0:
            raise ConfigError(f"--ilc-cutoff and --ilc-gain must be > 0, got "
                              f"{self.ilc_cutoff_hz} Hz and {self.ilc_gain}")
        if not 0.2 <= self.generalisation_speed <= 1.0:
            raise ConfigError("generalisation_speed: must be in [0.2, 1] (slower stays inside "
                              f"the learned velocities), got {self.generalisation_speed}")
        return self


def task_scenario(config: ScenarioConfig, plan: FeedforwardPlan) -> ScenarioConfig:
    """The experiment's scenario: `config` with friction on, the plan's trajectory, an ideal
    sensor (the sensor plays no part in tracking) and no compensator."""
    trajectory = dc.replace(config.trajectory, kind=plan.trajectory, seed=plan.seed)
    if plan.duration_s is not None:
        trajectory = dc.replace(trajectory, duration_s=float(plan.duration_s))
    return dc.replace(config, trajectory=trajectory,
                      friction=dc.replace(config.friction, enabled=True),
                      sensor=dc.replace(config.sensor, imperfections=False)).validate()


def time_scaled(traj: PiecewisePolynomial, speed: float) -> PiecewisePolynomial:
    """The same path at `speed` × the speed: q_new(t) = q(speed · t)."""
    t = np.arange(0.0, traj.end_time() / speed + 1e-9, 0.005)
    Q = traj.vector_values(np.minimum(speed * t, traj.end_time()))
    zero = np.zeros((Q.shape[0], 1))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, Q, zero, zero)


class Tracker:
    """Runs a trajectory with a feedforward and measures how well the arm follows it."""

    def __init__(self, config: ScenarioConfig):
        self.config = config
        station = build_station(config)  # plans the task trajectory once
        self.task = station.trajectory
        self.scene = station.scene
        self.n = station.plant.num_positions(station.scene.arm)
        self.control_plant = make_control_plant(config, station.scene)
        self._control_context = self.control_plant.CreateDefaultContext()
        self._plant = station.plant
        self._context = self._plant.CreateDefaultContext()
        self.dt = station.period

    def run(self, trajectory, feedforward=None) -> dict:
        station = build_station(self.config, trajectory=trajectory, feedforward=feedforward)
        result = simulate(station, progress=False)
        log = result.log
        t = log[col.TIME].to_numpy()
        n = self.n
        q = log[col.joint_columns(col.Q, n)].to_numpy()
        v = log[col.joint_columns(col.QD, n)].to_numpy()
        q_d = trajectory.vector_values(t).T
        v_d = trajectory.derivative(1).vector_values(t).T
        a_d = trajectory.derivative(2).vector_values(t).T
        applied = np.zeros_like(q)
        confidence = np.ones_like(q)
        if station.feedforward_log is not None:
            ff = station.feedforward_log.FindLog(result.context)
            keep = ff.sample_times() > 0.5 * self.config.time_step
            status = ff.data().T[keep]
            applied, confidence = status[:, :n], status[:, 2 * n:]
        # The plant's v̇ at row k+1 is that of the step that started at row k, the step the
        # torques of row k drove (see simulate's module docstring).
        a = log[col.joint_columns(col.QDD, n)].to_numpy()
        a_step = np.vstack([a[1:], a[-1:]])
        c = self.config.controller
        e = q_d - q
        feedback = self.mass_times(q, c.kp * e + c.kd * (v_d - v))
        # τ − ID̂(q, v, v̇): what the model lacked at the state the arm was in (N·m).
        model_error = applied + self.mass_times(q, c.kp * e + c.kd * (v_d - v) + a_d - a_step)
        tip = self.tool_tip(q) - self.tool_tip(q_d)
        joint_rms = np.sqrt((e**2).mean(axis=0))
        return {
            "t": t, "X_desired": np.hstack([q_d, v_d, a_d]), "X_actual": np.hstack([q, v, a_step]),
            "feedback": feedback, "model_error": model_error, "applied": applied,
            "confidence": confidence,
            "joint_rms_mrad": float(1e3 * np.sqrt((e**2).sum(axis=1).mean())),
            "joint_rms_per_joint_mrad": (1e3 * joint_rms).round(4).tolist(),
            "tip_rms_mm": float(1e3 * np.sqrt((tip**2).sum(axis=1).mean())),
            "tip_max_mm": float(1e3 * np.linalg.norm(tip, axis=1).max()),
            "scaled_down_fraction": float((confidence < 1).any(axis=1).mean()),
            "zero_fraction": float((confidence <= 0).any(axis=1).mean()),
            "wall_time_s": float(result.timing["wall_time_s"]),
        }

    def mass_times(self, q, w) -> np.ndarray:
        """M̂(q) w per row, with the controller's model M̂ (N·m for w in rad/s²)."""
        plant, context = self.control_plant, self._control_context
        out = np.empty_like(q)
        for i in range(len(q)):
            plant.SetPositions(context, q[i])
            out[i] = plant.CalcMassMatrix(context) @ w[i]
        return out

    def tool_tip(self, q) -> np.ndarray:
        """Tool-tip positions p_WTip (N, 3), m, for joint angles q (N, n)."""
        plant, context, frame = self._plant, self._context, self.scene.tool_tip_frame()
        out = np.empty((len(q), 3))
        for i in range(len(q)):
            plant.SetPositions(context, self.scene.arm, q[i])
            out[i] = frame.CalcPoseInWorld(context).translation()
        return out


def _training_data(run: dict, target: str):
    if target == "model_error":
        return run["X_actual"], run["model_error"]
    return run["X_desired"], run["applied"] + run["feedback"]


def _row(method: str, iteration: int, run: dict, fit_s: float = 0.0) -> dict:
    return {"method": method, "iteration": iteration, "joint_rms_mrad": run["joint_rms_mrad"],
            "tip_rms_mm": run["tip_rms_mm"], "tip_max_mm": run["tip_max_mm"],
            "scaled_down_fraction": run["scaled_down_fraction"], "fit_s": fit_s,
            "joint_rms_per_joint_mrad": run["joint_rms_per_joint_mrad"]}


def run_feedforward_experiment(config: ScenarioConfig | None = None,
                               plan: FeedforwardPlan | None = None, out_dir=None, *,
                               progress: bool = True) -> dict:
    """Runs the iterations (GP and ILC) and the generalisation runs; writes to `out_dir`
    (``summary.json``, ``iterations.csv``, ``tracking.png``, ``feedforward_model.ftd``) when
    given. Returns the summary."""
    plan = (plan or FeedforwardPlan()).validate()
    scenario = task_scenario(config or ScenarioConfig(), plan)
    start = time.perf_counter()
    runs_total = 1 + 2 * plan.iterations + 3
    bar = tqdm(total=runs_total, desc="learn-feedforward", unit="run", disable=not progress)
    tracker = Tracker(scenario)
    task = tracker.task
    first = tracker.run(task)
    bar.update()
    rows = [_row("none", 0, first)]

    # The learned feedforward (see FeedforwardPlan.target for what it is fitted on).
    last, model, ff, data = first, None, None, []
    for k in range(1, plan.iterations + 1):
        t0 = time.perf_counter()
        X, y = _training_data(last, plan.target)
        data = [*data, (X, y)] if plan.target == "model_error" else [(X, y)]
        model = fit_feedforward_gp(np.vstack([d[0] for d in data]),
                                   np.vstack([d[1] for d in data]),
                                   max_points=plan.max_points,
                                   optimize_points=plan.optimize_points,
                                   random_state=plan.seed + k)
        fit_s = time.perf_counter() - t0
        ff = LearnedFeedforward(model, n_joints=tracker.n, trust_ratio=plan.trust_ratio,
                                reject_ratio=plan.reject_ratio)
        last = tracker.run(task, ff)
        rows.append(_row("gp", k, last, fit_s))
        bar.update()
        bar.set_postfix(gp_tip_mm=f"{last['tip_rms_mm']:.2f}")

    # ILC: u_{k+1} = Q(u_k + γ L e_k) on the time grid of the log (row 0 at t = 0), with
    # L e = the learning signal less the applied correction (τ_fb, or M̂(kp e + kd ė + ë)).
    u = np.zeros((len(first["t"]) + 1, tracker.n))
    last = first
    for k in range(1, plan.iterations + 1):
        learn = _training_data(last, plan.target)[1] - last["applied"]
        fb = np.vstack([learn[:1], learn])
        u = ilc_update(u, fb, tracker.dt, gain=plan.ilc_gain, cutoff_hz=plan.ilc_cutoff_hz)
        last = tracker.run(task, TimeIndexedFeedforward(u, tracker.dt))
        rows.append(_row("ilc", k, last))
        bar.update()
        bar.set_postfix(ilc_tip_mm=f"{last['tip_rms_mm']:.2f}")

    # Generalisation: the task's path at another speed, with each final correction.
    new = time_scaled(task, plan.generalisation_speed)
    general = {}
    for name, system in (("none", None), ("gp", LearnedFeedforward(
            model, n_joints=tracker.n, trust_ratio=plan.trust_ratio,
            reject_ratio=plan.reject_ratio)), ("ilc", TimeIndexedFeedforward(u, tracker.dt))):
        general[name] = tracker.run(new, system)
        bar.update()
    bar.close()

    table = pd.DataFrame(rows)
    summary = _summary(table, general, plan, scenario, time.perf_counter() - start)
    for method in ("gp", "ilc"):
        s = summary["task"][method]
        logger.info("%s: tool-tip RMS %.3f → %.3f mm (%.1f×) in %d iterations", method,
                    s["tip_rms_mm_first"], s["tip_rms_mm_last"], s["improvement"],
                    plan.iterations)
    if out_dir is not None:
        write_outputs(Path(out_dir), table, summary, model, plan)
    return summary


def _summary(table: pd.DataFrame, general: dict, plan: FeedforwardPlan, scenario, wall: float):
    base = table.iloc[0]
    task = {}
    for method in ("gp", "ilc"):
        rows = table[table.method == method]
        tips = [float(base.tip_rms_mm), *rows.tip_rms_mm.astype(float)]
        within_5 = min(tips[: 6])
        task[method] = {
            "tip_rms_mm": tips,
            "joint_rms_mrad": [float(base.joint_rms_mrad), *rows.joint_rms_mrad.astype(float)],
            "tip_rms_mm_first": tips[0], "tip_rms_mm_last": tips[-1],
            "improvement": tips[0] / tips[-1],
            "improvement_within_5": tips[0] / within_5,
        }
    reference = general["none"]["tip_rms_mm"]
    generalisation = {
        "speed": plan.generalisation_speed,
        **{name: {"tip_rms_mm": run["tip_rms_mm"], "joint_rms_mrad": run["joint_rms_mrad"],
                  "improvement": reference / run["tip_rms_mm"],
                  "scaled_down_fraction": run["scaled_down_fraction"],
                  "zero_fraction": run["zero_fraction"]}
           for name, run in general.items()},
    }
    return {
        "plan": dc.asdict(plan),
        "friction": dc.asdict(scenario.friction),
        "duration_s": scenario.trajectory.duration_s,
        "task": task,
        "generalisation": generalisation,
        "goals": {
            "tip_rms_falls_5x_within_5_iterations": task["gp"]["improvement_within_5"] >= 5,
            "gp_keeps_3x_on_new_trajectory": generalisation["gp"]["improvement"] >= 3,
            "ilc_does_not_keep_3x": generalisation["ilc"]["improvement"] < 3,
        },
        "wall_time_s": wall,
    }


def write_outputs(out: Path, table: pd.DataFrame, summary: dict, model, plan) -> None:
    """summary.json, iterations.csv, tracking.png and the final model, each atomically."""
    out.mkdir(parents=True, exist_ok=True)
    summary = {**summary, "provenance": result_provenance()}
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    with atomic_path(out / "iterations.csv") as tmp:
        table.to_csv(tmp, index=False)
    n = model.n_joints_
    save_model(model, out / "feedforward_model.ftd",
               target_names=[f"tau_ff_{i}" for i in range(n)], target_units=["N*m"] * n,
               sensor_frame="joints",
               extra={"kind": "learned_feedforward", "trust_ratio": plan.trust_ratio,
                      "reject_ratio": plan.reject_ratio,
                      "trajectory": plan.trajectory, "iterations": plan.iterations})
    plot_tracking(summary, out / "tracking.png")


def plot_tracking(summary: dict, path: Path) -> None:
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4), gridspec_kw={"width_ratios": [2, 1]})
    for method, label in (("gp", "learned feedforward (GP)"), ("ilc", "ILC (time-indexed)")):
        tips = summary["task"][method]["tip_rms_mm"]
        ax.semilogy(range(len(tips)), tips, "o-", label=label)
    ax.set_xlabel("iteration (0: no correction)")
    ax.set_ylabel("tool-tip tracking RMS (mm)")
    ax.set_title(f"task: {summary['plan']['trajectory']}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    g = summary["generalisation"]
    names = ["none", "gp", "ilc"]
    bx.bar(names, [g[k]["tip_rms_mm"] for k in names], color=["grey", "C0", "C1"])
    bx.set_yscale("log")
    bx.set_ylabel("tool-tip RMS (mm)")
    bx.set_title(f"new trajectory: same path at {g['speed']:.0%} speed")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)
