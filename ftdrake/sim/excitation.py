"""Training motion planned for a task: the ``task_covering`` trajectory kind.

A compensator is only as good as its training data is like the motion it will see, and a
payload fit only as good as its data excites the payload's parameters. The other free-motion
kinds move around the home pose; the contact scenario's approach to another surface (the wall)
takes the arm where none of them goes. ``task_covering`` plans the training motion from the
task itself:

1. **The task's configurations** (:func:`task_approach_configurations`): for every surface of
   ``task.surfaces``, the joint configurations the contact kind passes through before it
   touches — the straight joint-space lines home → hover (5 cm off the surface) → near (5 mm
   off), from the same inverse kinematics (:meth:`RobotGeometry.press_poses`).
2. **Candidate waypoints**: the task's anchors (home; each surface's hover pose and its pose
   ``rehearsal_height_m`` off the surface) each with perturbed copies (``COVERING_SPREAD`` of
   the ``fourier`` kind's amplitude per joint), and free waypoints around home like the
   ``random`` kind's. Candidates outside the joint limits (less ``LIMIT_MARGIN_RAD``) or
   closer than the clearance margin to the environment are dropped.
3. **A greedy choice** of the waypoints, rest-to-rest min-jerk moves between them: from the
   current waypoint, the next is the candidate that minimises

       J = log10 cond(Ā) + gap / COVERAGE_SCALE_RAD

   where ``Ā`` is the payload regressor (the physics compensator's 6 × 16 rows: 10 inertial
   parameters and 6 biases, :func:`~ftdrake.compensation.identification.payload_identification.
   payload_regressor`) stacked over the trajectory so far plus the move, torque rows scaled by
   ``TORQUE_ROW_SCALE`` and columns normalised (as the identification does); and ``gap`` the
   RMS over the task's configurations of the distance (rad, Euclidean in q) to the nearest
   sample of the trajectory: the first term excites, the second covers. Each move takes the
   longer of ``SEGMENT_S`` and what the speed (``speed_fraction`` of each joint's limit) and
   acceleration limits allow; a move must clear the environment by the margin at every
   sample, and the arm must still be able to get home in the time left. The last move returns
   home and is stretched to end at ``duration_s``.

The last few millimetres of each approach (the tool closer to the surface than the clearance
margin, 2 cm) stay out of reach: training motion must not touch. The coverage is reported
over the whole approach all the same (:func:`coverage_gap`).

Everything is deterministic given ``trajectory.seed`` (the perturbations and free waypoints).
The regressor is computed by the compiled serial chain of the scene's own plant
(:class:`~ftdrake.physics.chain.SerialChain`), so a different arm, tool or environment gets its
own plan.
"""

from __future__ import annotations

import numpy as np

from ..compensation.identification.payload_identification import payload_regressor
from ..errors import TrajectoryError
from ..physics.chain import SerialChain
from .trajectories import (
    _FOURIER_AMPLITUDE,
    JointLimits,
    RobotGeometry,
    _min_jerk_path,
    _spline,
)

#: Nominal duration of one move between waypoints (s).
SEGMENT_S = 2.0
#: Perturbed copies of each task anchor: spread as a fraction of the ``fourier`` amplitude.
COVERING_SPREAD = 0.6
COPIES_PER_ANCHOR = 8
FREE_CANDIDATES = 24
#: Candidates stay this far inside each joint's position limits (rad).
LIMIT_MARGIN_RAD = 0.05
#: A coverage gap of this much (rad) costs as much as a factor 10 in condition number.
COVERAGE_SCALE_RAD = 0.05
#: Torque rows (N·m) are multiplied by this (1/m) so that they weigh like forces (N) at a
#: 0.1 m lever: the identification weights axes by their residuals, unknown before the data.
TORQUE_ROW_SCALE = 10.0
#: Samples per second of a move for the regressor, the coverage and the clearance checks.
PLAN_RATE_HZ = 10.0
#: Samples on each line of a task's approach (home → hover, hover → near).
APPROACH_SAMPLES = 20
CLEARANCE_M = 0.02  # as RobotGeometry.clear_of_environment's default margin

# Min-jerk s(τ) = 10τ³ − 15τ⁴ + 6τ⁵: peak ds/dτ and |d²s/dτ²|.
_PEAK_SPEED = 1.875
_PEAK_ACCELERATION = 10.0 / np.sqrt(3.0)


def task_approach_configurations(config, home_q, robot: RobotGeometry,
                                 per_path: int = APPROACH_SAMPLES) -> np.ndarray:
    """(K, n) joint configurations (rad) the contact kind passes through before touching,
    for every surface of ``task.surfaces``: `per_path` samples on each of the joint-space
    lines home → hover and hover → near (:meth:`RobotGeometry.press_poses`; the contact
    kind's min-jerk moves follow these lines). Surfaces the arm cannot reach are left out."""
    home_q = np.asarray(home_q, dtype=float)
    s = np.linspace(0.0, 1.0, per_path)[:, None]
    samples = []
    for surface in robot.surfaces():
        try:
            hover, near, _ = robot.press_poses(surface, config.press_depth_m, home_q)
        except TrajectoryError:
            continue  # the contact kind cannot go there either
        samples += [home_q + s * (hover - home_q), hover + s * (near - hover)]
    if not samples:
        raise TrajectoryError("no surface of scenario.task.surfaces is reachable from home_q; "
                              "the task_covering kind needs at least one")
    return np.vstack(samples)


class RegressorStack:
    """The payload regressor of a sequence of moves, as its 16 × 16 Gram matrix ĀᵀĀ.

    Rows are those of
    :func:`~ftdrake.compensation.identification.payload_identification.payload_regressor` (reading =
    A·[m, m·c, I_So, biases]) with the torque rows scaled by ``TORQUE_ROW_SCALE``.
    """

    def __init__(self, robot: RobotGeometry):
        self._chain = SerialChain.from_plant(robot.plant, robot.sensor_frame, robot.arm)
        self.gram = np.zeros((16, 16))

    def rows(self, q, v, vdot) -> np.ndarray:
        """(6N, 16) scaled regressor rows of samples (N × n each of q, q̇, q̈)."""
        kin = self._chain.evaluate(q, v, vdot)
        A = payload_regressor(kin.w_WS_S, kin.alpha_WS_S, kin.a_WSo_S - kin.g_S)
        A[:, 3:, :] *= TORQUE_ROW_SCALE
        return A.reshape(-1, 16)

    def condition_with(self, rows=None) -> float:
        """The condition number of the column-normalised stack (plus `rows`): ∞ when some
        combination of parameters is not excited at all."""
        gram = self.gram if rows is None else self.gram + rows.T @ rows
        return gram_condition(gram)


def gram_condition(gram) -> float:
    """cond(A·D⁻¹) from G = AᵀA, D = diag(‖columns of A‖): √ of the normalised Gram's."""
    d = np.sqrt(np.diag(gram))
    if np.any(d <= 0):
        return np.inf
    eig = np.linalg.eigvalsh(gram / np.outer(d, d))
    return float(np.sqrt(eig[-1] / eig[0])) if eig[0] > 1e-15 * eig[-1] else np.inf


def regressor_condition_number(traj, robot: RobotGeometry, dt: float = 1.0 / PLAN_RATE_HZ
                               ) -> float:
    """The condition number of the column-normalised payload regressor (16 parameters,
    torque rows × ``TORQUE_ROW_SCALE``) stacked over `traj` sampled every `dt` s: how well a
    fit on this motion determines the payload (lower is better)."""
    t = np.arange(traj.start_time(), traj.end_time() + 1e-12, dt)
    q, v, a = (np.column_stack([f.value(ti).ravel() for ti in t]).T
               for f in (traj, traj.derivative(1), traj.derivative(2)))
    stack = RegressorStack(robot)
    return stack.condition_with(stack.rows(q, v, a))


def coverage_gap(targets, samples) -> float:
    """The largest distance (rad, Euclidean in q) from a row of `targets` to its nearest row
    of `samples`: how far the task goes from where the motion went."""
    targets, samples = np.atleast_2d(targets), np.atleast_2d(samples)
    d2 = ((targets[:, None, :] - samples[None, :, :]) ** 2).sum(axis=2)
    return float(np.sqrt(d2.min(axis=1).max()))


def _rms_gap(targets, samples) -> float:
    """The RMS over `targets` of the distance to the nearest sample: unlike the largest, it
    rewards every move that covers more of the task, so the greedy choice is not stuck
    behind the one farthest target."""
    d2 = ((targets[:, None, :] - samples[None, :, :]) ** 2).sum(axis=2)
    return float(np.sqrt(d2.min(axis=1).mean()))


def task_covering(config, home_q, limits: JointLimits, robot: RobotGeometry):
    """The ``task_covering`` trajectory (module docstring), from `home_q` back to it over
    ``config.duration_s``; `limits` are the arm's, `robot` the scene's geometry."""
    if robot is None:
        raise TrajectoryError("the task_covering kind needs the robot's geometry (the task's "
                              "inverse kinematics and the clearance checks)")
    home_q = np.asarray(home_q, dtype=float)
    rng = np.random.default_rng(config.seed)
    targets = task_approach_configurations(config, home_q, robot)
    speed = limits.velocity * config.speed_fraction
    planner = _Planner(robot, limits, speed, targets, home_q)
    candidates = _candidates(config, home_q, limits, robot, rng)
    points, times = planner.choose(candidates, config.duration_s)
    return _spline(_min_jerk_path(np.array(times), np.array(points)), config.duration_s)


def _candidates(config, home_q, limits, robot, rng) -> np.ndarray:
    """Task anchors with perturbed copies, and free waypoints around home, all within the
    limits and clear of the environment."""
    n = len(home_q)
    amplitude = _FOURIER_AMPLITUDE[:n]
    anchors = [home_q]
    for surface in robot.surfaces():
        for depth in (-0.05, -config.rehearsal_height_m):  # hover, and rehearsal height
            try:
                anchors.append(robot.press_poses(surface, depth, home_q)[2])
            except TrajectoryError:
                continue
    points = []
    for anchor in anchors:
        points.append(anchor)
        points += [anchor + COVERING_SPREAD * amplitude * rng.uniform(-1, 1, n)
                   for _ in range(COPIES_PER_ANCHOR)]
    points += [home_q + amplitude * rng.uniform(-1, 1, n) for _ in range(FREE_CANDIDATES)]
    points = np.array(points)
    lo, hi = limits.lower + LIMIT_MARGIN_RAD, limits.upper - LIMIT_MARGIN_RAD
    inside = np.all((points >= lo) & (points <= hi), axis=1)
    return np.array([p for p in points[inside] if robot.clear_at(p, CLEARANCE_M)])


class _Planner:
    """The greedy choice of waypoints (module docstring, step 3)."""

    def __init__(self, robot, limits, speed, targets, home_q):
        self.robot, self.limits, self.speed = robot, limits, speed
        self.targets, self.home_q = targets, home_q
        self.stack = RegressorStack(robot)

    def move_time(self, a, b) -> float:
        """The shortest min-jerk move a → b within the speed and acceleration limits, at
        least SEGMENT_S."""
        d = np.abs(b - a)
        return float(max(SEGMENT_S, np.max(_PEAK_SPEED * d / self.speed),
                         np.max(np.sqrt(_PEAK_ACCELERATION * d / self.limits.acceleration))))

    def move(self, a, b, duration):
        """Samples (q, q̇, q̈) of the min-jerk move a → b over `duration` at PLAN_RATE_HZ."""
        tau = np.linspace(0.0, 1.0, max(3, round(duration * PLAN_RATE_HZ) + 1))[:, None]
        d = (b - a)[None, :]
        q = a + d * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)
        v = d * (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
        acc = d * (60 * tau - 180 * tau**2 + 120 * tau**3) / duration**2
        return q, v, acc

    def choose(self, candidates, duration):
        """Waypoints and their times, home → … → home over `duration`."""
        points, times = [self.home_q], [0.0]
        visited = self.home_q[None, :]
        usable = np.ones(len(candidates), dtype=bool)
        while True:
            best = self._best_next(points[-1], times[-1], candidates, usable, visited, duration)
            if best is None:
                break
            k, T, samples, rows = best
            usable[k] = False
            points.append(candidates[k])
            times.append(times[-1] + T)
            visited = np.vstack([visited, samples])
            self.stack.gram += rows.T @ rows
        if len(points) == 1:  # not one move out and back fits
            raise TrajectoryError(
                f"trajectory.duration_s: {duration} s is too short for a task_covering "
                f"trajectory (one move takes at least {SEGMENT_S} s); give it at least "
                f"{2 * SEGMENT_S:.0f} s")
        points.append(self.home_q)
        times.append(duration)
        return points, times

    def _best_next(self, here, now, candidates, usable, visited, duration):
        """(index, move time, q samples, regressor rows) of the best next waypoint, or None."""
        scored = []
        for k in np.flatnonzero(usable):
            target = candidates[k]
            T = self.move_time(here, target)
            if now + T + self.move_time(target, self.home_q) > duration:
                continue
            q, v, a = self.move(here, target, T)
            rows = self.stack.rows(q, v, a)
            cond = self.stack.condition_with(rows)
            gap = _rms_gap(self.targets, np.vstack([visited, q]))
            score = np.log10(min(cond, 1e12)) + gap / COVERAGE_SCALE_RAD
            scored.append((score, k, T, q, rows))
        for _, k, T, q, rows in sorted(scored, key=lambda s: s[0]):
            if all(self.robot.clear_at(qi, CLEARANCE_M) for qi in q):
                return k, T, q, rows
        return None


__all__ = [
    "RegressorStack",
    "coverage_gap",
    "gram_condition",
    "regressor_condition_number",
    "task_approach_configurations",
    "task_covering",
]
