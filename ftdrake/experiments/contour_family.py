"""Contours where the time index does not match: does a learned correction transfer?

The paper's argument for a state-indexed correction over ILC is that it carries over to motion
it has not run. :func:`run_contour_family` tests it on a family of contours
(:data:`MEMBERS`, :data:`POOL`, :func:`family_plan`): each method learns on the base hole
(:class:`~ftdrake.experiments.contour.ContourPlan`'s ``hole``) for ``iterations`` runs, as in
:func:`~ftdrake.experiments.contour.run_contour_experiment`; then its final correction runs,
without relearning, on each member of the family (another cutting speed, the other direction,
holes Ø 10–60 mm elsewhere in the workspace, tilted planes, a 3-D path with the tool
reoriented, a slot with corners). Per member and method, the kept improvement
``K = radial RMS without learning ÷ radial RMS with the correction learned elsewhere``.

Methods: ``two_part_timed`` and ``two_part_contour`` (torque feedforward plus the reference
correction from a timed or an untimed contour measurement, both indexed by the desired state),
``ilc`` (the motor reference's offsets indexed by time, replayed at the same times), and
``pooled``: the two-part timed correction learned from the pooled data of several earlier
contours (the base hole, then each contour of the family's ``pool`` in turn, each cut with the
correction learned so far and its run's data added). Every fit keeps ``max_points`` rows per
joint chosen by farthest-point selection
(:func:`~ftdrake.systems.learned_feedforward.fit_feedforward_gp`), so the GP stays the same
size however many contours are pooled. The learning curve: the radial RMS on one member
(``curve_contour``, not in the pool) against the number of contours pooled.

Outputs (:func:`write_family`): ``transfer.json`` ``{contour: {method: K}}``,
``learning_curve.json`` and ``summary.json`` (every radial RMS, each contour's definition, the
goals of issue 41 and the provenance).
"""

from __future__ import annotations

import dataclasses as dc
import json
import logging
import time
from pathlib import Path

import numpy as np

from ..config import ScenarioConfig
from ..config.contour import HoleConfig
from ..errors import ConfigError
from ..io import atomic_write_text
from .contour import (
    ContourPlan,
    HoleRunner,
    Learner,
    _fit,
    contour_scenario,
    tool_error_joint,
)

logger = logging.getLogger(__name__)

#: The kept improvement's columns, in order, and the learner each comes from.
TRANSFER_METHODS = {"two_part_timed": "timed", "two_part_contour": "contour", "ilc": "ilc",
                    "pooled": "pooled"}
# Tilts of the cutting plane (normals in W).
_TILT_X20 = [0.0, -float(np.sin(np.radians(20))), float(np.cos(np.radians(20)))]
_TILT_Y20 = [float(np.sin(np.radians(20))), 0.0, float(np.cos(np.radians(20)))]

#: The family's contours (not learned on), by name.
MEMBERS = {
    "speed_60": HoleConfig(diameter_m=0.020, speed_m_s=0.060),
    "reversed": HoleConfig(diameter_m=0.020, direction="cw"),
    "hole_40_elsewhere": HoleConfig(diameter_m=0.040, offset_m=[0.06, 0.05, -0.03]),
    "hole_10_elsewhere": HoleConfig(diameter_m=0.010, offset_m=[-0.05, -0.06, 0.02]),
    "hole_60_elsewhere": HoleConfig(diameter_m=0.060, offset_m=[0.02, -0.08, -0.05]),
    "tilted_x20": HoleConfig(diameter_m=0.020, normal=_TILT_X20),
    "tilted_y20": HoleConfig(diameter_m=0.030, normal=_TILT_Y20, offset_m=[-0.03, 0.0, 0.0]),
    "3d_reoriented": HoleConfig(diameter_m=0.030, height_m=0.004, tool_tilt_deg=10.0),
    "slot_corners": HoleConfig(slot_m=[0.040, 0.012], corner_radius_m=0.002,
                               offset_m=[0.0, 0.04, 0.0]),
}
#: Earlier contours pooled after the base hole, in the order they are cut.
POOL = {
    "pool_hole_30_cw": HoleConfig(diameter_m=0.030, speed_m_s=0.045, direction="cw",
                                  offset_m=[-0.05, 0.05, 0.02]),
    "pool_hole_16": HoleConfig(diameter_m=0.016, speed_m_s=0.020,
                               offset_m=[0.04, -0.06, -0.03]),
    "pool_slot_tilted": HoleConfig(slot_m=[0.030, 0.016], normal=[0.2, 0.2, 0.96],
                                   offset_m=[0.03, 0.03, 0.0]),
    "pool_hole_24_fast": HoleConfig(diameter_m=0.024, speed_m_s=0.050,
                                    offset_m=[-0.03, -0.03, -0.02]),
}


@dc.dataclass
class FamilyPlan:
    """What :func:`run_contour_family` runs: the learning on the base hole (``contour``'s
    ``hole``, ``iterations``, GP sizes, measurements, seed), the members and the pool."""

    contour: ContourPlan = dc.field(default_factory=lambda: ContourPlan(iterations=3))
    members: dict = dc.field(default_factory=lambda: dict(MEMBERS))
    pool: dict = dc.field(default_factory=lambda: dict(POOL))
    curve_contour: str = "hole_40_elsewhere"
    name: str = "full"

    def validate(self) -> FamilyPlan:
        self.contour.validate()
        if not self.members:
            raise ConfigError("family: no members to transfer to; name at least one contour")
        if self.curve_contour not in self.members:
            raise ConfigError(f"family.curve_contour: {self.curve_contour!r} is not a member "
                              f"({sorted(self.members)})")
        overlap = set(self.members) & set(self.pool)
        if overlap:
            raise ConfigError(f"family: {sorted(overlap)} both a member and in the pool; a "
                              "member must be a contour the pooled correction has not run")
        for name, hole in {**self.members, **self.pool}.items():
            hole.validate(f"family.{name}")
        return self


def family_plan(name: str, iterations: int | None = None, seed: int = 0,
                members: list[str] | None = None) -> FamilyPlan:
    """The named family: ``quick`` (another speed, the other direction, one new hole; two
    earlier contours pooled after the base; 2 iterations) or ``full`` (every member of
    :data:`MEMBERS`, every contour of :data:`POOL`; 5 iterations). `members`: these members
    of :data:`MEMBERS` instead of the family's (the learning curve on the first of them
    unless the family's curve contour is among them)."""
    chosen = members
    if name == "quick":
        members = {k: MEMBERS[k] for k in ("speed_60", "reversed", "hole_40_elsewhere")}
        pool = {k: POOL[k] for k in ("pool_hole_30_cw", "pool_hole_16")}
        default_iterations = 2
    elif name == "full":
        members, pool, default_iterations = dict(MEMBERS), dict(POOL), 5
    else:
        raise ConfigError(f"--family: 'quick' or 'full', got {name!r}")
    if chosen:
        unknown = sorted(set(chosen) - set(MEMBERS))
        if unknown:
            raise ConfigError(f"--members: unknown {unknown}; choose from {sorted(MEMBERS)}")
        members = {k: MEMBERS[k] for k in chosen}
    curve = "hole_40_elsewhere" if "hole_40_elsewhere" in members else next(iter(members))
    contour = ContourPlan(iterations=iterations or default_iterations,
                          methods=("timed", "contour", "ilc")).with_seed(seed)
    return FamilyPlan(contour, members, pool, curve, name).validate()


class Pool:
    """The pooled data of several contours: part one's (motor states → the torque the model
    lacked) and part two's (desired states → the transmission error in joint space, from the
    timed measurement); :meth:`learner` fits both on all of it."""

    def __init__(self, runner: HoleRunner, plan: ContourPlan):
        self.runner, self.plan = runner, plan
        self.torque: list = []
        self.reference: list = []
        self.contours: list[str] = []

    def add(self, name: str, task, runs: list[dict]) -> None:
        """Adds a contour's runs: part one's data from each, part two's from the last (the
        transmission error is measured whole in every run; the last ran with the most
        learned correction)."""
        for run in runs:
            self.torque.append((run["X_motor"], run["model_error"]))
        rows, dq = tool_error_joint(task, runs[-1], "timed", self.plan, "transmission")
        self.reference.append((task.X_d[rows], dq))
        self.contours.append(name)

    def size(self, learner: Learner) -> dict:
        """Rows pooled and rows each fitted GP kept (the farthest-point subset)."""
        return {"contours": list(self.contours),
                "torque_rows": sum(len(d[0]) for d in self.torque),
                "torque_rows_kept": len(learner.torque_model.subset_indices_),
                "reference_rows": sum(len(d[0]) for d in self.reference),
                "reference_rows_kept": len(learner.reference_model.subset_indices_)}

    def learner(self, base_task) -> Learner:
        """A two-part timed learner holding the GPs fitted on the pooled data."""
        learner = Learner("timed", self.runner, base_task, self.plan)
        seed = self.plan.seed + 1000 * len(self.contours)
        learner.torque_model = _fit(np.vstack([d[0] for d in self.torque]),
                                    np.vstack([d[1] for d in self.torque]), self.plan, seed)
        learner.reference_model = _fit(np.vstack([d[0] for d in self.reference]),
                                       np.vstack([d[1] for d in self.reference]), self.plan,
                                       seed + 100)
        return learner


def _rms(run: dict) -> float:
    return float(run["radial_rms_mm"])


def _learn_base(runner, base, plan: ContourPlan, progress: bool):
    """Each method's learning on the base hole; returns (learners, the timed learner's runs
    with the first, every radial RMS)."""
    first = runner.run(base)
    learners, timed_runs, rms = {}, [first], {"none": [_rms(first)]}
    for method in plan.methods:
        learner = learners[method] = Learner(method, runner, base, plan)
        learner.record_applied(None)
        last, rms[method] = first, [_rms(first)]
        for k in range(1, plan.iterations + 1):
            learner.update(last, k)
            reference = learner.reference(base)
            learner.record_applied(reference)
            last = runner.run(base, reference, learner.feedforward())
            rms[method].append(_rms(last))
            if method == "timed":
                timed_runs.append(last)
            if progress:
                logger.warning("base hole, %s %d: radial RMS %.4f mm", method, k, _rms(last))
    return learners, timed_runs, rms


def run_contour_family(config: ScenarioConfig | None = None, plan: FamilyPlan | None = None,
                       out_dir=None, *, progress: bool = True,
                       provenance: dict | None = None) -> dict:
    """Runs the family (see the module docstring); writes its files to `out_dir` when given.
    Returns the summary (``transfer``, ``learning_curve``, ``radial_rms_mm``, ...)."""
    plan = (plan or family_plan("full")).validate()
    cplan = plan.contour
    start = time.perf_counter()
    runner = HoleRunner(contour_scenario(config or ScenarioConfig()))
    base = runner.task(cplan.hole)
    learners, timed_runs, base_rms = _learn_base(runner, base, cplan, progress)

    # Pooled learning: the base hole, then each earlier contour cut with the correction so far.
    pool = Pool(runner, cplan)
    pool.add("base", base, timed_runs)
    pooled = pool.learner(base)
    curve_task = runner.task(plan.members[plan.curve_contour])
    curve_none = runner.run(curve_task)
    curve = [_rms(curve_none)]
    pool_rms = {}

    def curve_point(learner):
        run = runner.run(curve_task, learner.reference(curve_task), learner.feedforward())
        curve.append(_rms(run))
        if progress:
            logger.warning("%s after %d contours pooled: radial RMS %.4f mm",
                           plan.curve_contour, len(pool.contours), curve[-1])
        return run

    curve_run = curve_point(pooled)
    for name, hole in plan.pool.items():
        task = runner.task(hole)
        run = runner.run(task, pooled.reference(task), pooled.feedforward())
        pool_rms[name] = _rms(run)
        pool.add(name, task, [run])
        pooled = pool.learner(base)
        curve_run = curve_point(pooled)

    curves = {plan.curve_contour: (curve_task, curve_none, curve_run)}
    transfer, member_rms = _transfer(runner, plan, learners, pooled, curves, progress)
    learning_curve = {
        "contour": plan.curve_contour,
        "contours_learned_from": list(range(len(curve))),
        "pooled": ["none", "base", *plan.pool],
        "radial_rms_mm": curve,
        "improvement": [curve[0] / v for v in curve],
    }
    summary = {
        "family": plan.name,
        "plan": json.loads(json.dumps(dc.asdict(plan), default=list)),
        "base_hole_radial_rms_mm": base_rms,
        "radial_rms_mm": member_rms,
        "transfer": transfer,
        "learning_curve": learning_curve,
        "pool_first_cut_radial_rms_mm": pool_rms,
        "pool_size": pool.size(pooled),
        "goals": _goals(transfer, learning_curve),
        "wall_time_s": time.perf_counter() - start,
    }
    if provenance is not None:
        summary["provenance"] = dict(provenance)
    if out_dir is not None:
        write_family(Path(out_dir), summary)
    return summary


def _transfer(runner, plan: FamilyPlan, learners: dict, pooled, done: dict, progress: bool):
    """Each method's final correction on each member, without relearning: ({member:
    {column: K}}, {member: {"none" or column: radial RMS}}). `done`: members already run
    without correction and with the pooled one, {name: (task, none run, pooled run)}."""
    transfer, member_rms = {}, {}
    for name, hole in plan.members.items():
        task, none, pooled_run = done.get(name) or (runner.task(hole), None, None)
        none = none or runner.run(task)
        member_rms[name] = {"none": _rms(none)}
        for column, method in TRANSFER_METHODS.items():
            if method == "pooled":
                run = pooled_run or runner.run(task, pooled.reference(task),
                                               pooled.feedforward())
            elif method in learners:
                learner = learners[method]
                run = runner.run(task, learner.reference(task), learner.feedforward())
            else:
                continue
            member_rms[name][column] = _rms(run)
        transfer[name] = {k: member_rms[name]["none"] / v for k, v in member_rms[name].items()
                          if k != "none"}
        if progress:
            logger.warning("%s: kept improvement %s", name,
                           ", ".join(f"{k} {v:.1f}×" for k, v in transfer[name].items()))
    return transfer, member_rms


#: Members on which the time index does not match the learned run's.
TIME_MISMATCH = ("speed_60", "reversed", "hole_40_elsewhere", "hole_10_elsewhere",
                 "hole_60_elsewhere", "tilted_x20", "tilted_y20", "3d_reoriented",
                 "slot_corners")


def _goals(transfer: dict, curve: dict) -> dict:
    """Issue 41's goals: on each member, two-part (timed or contour) keeps ≥ 5× where ILC
    keeps < 2×; pooled learning from ≥ 3 contours reaches ≥ 10× on the curve's contour."""
    goals = {}
    for name, k in transfer.items():
        if name in TIME_MISMATCH and {"two_part_timed", "ilc"} <= set(k):
            two_part = max(k["two_part_timed"], k.get("two_part_contour", 0.0))
            goals[f"{name}: two-part keeps >= 5x, ILC < 2x"] = bool(two_part >= 5
                                                                    and k["ilc"] < 2)
    if len(curve["improvement"]) > 3:
        goals[f"pooled from >= 3 contours >= 10x on {curve['contour']}"] = bool(
            curve["improvement"][3] >= 10)
    return goals


def write_family(out: Path, summary: dict) -> None:
    """``transfer.json``, ``learning_curve.json`` and ``summary.json``, each atomically."""
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "transfer.json", json.dumps(summary["transfer"], indent=2) + "\n")
    atomic_write_text(out / "learning_curve.json",
                      json.dumps(summary["learning_curve"], indent=2) + "\n")
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")


__all__ = ["FamilyPlan", "Pool", "family_plan", "run_contour_family"]
