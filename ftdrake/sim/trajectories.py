"""Joint trajectories that drive the arm: excitation, the study's reference motion, contact.

Every trajectory is a ``PiecewisePolynomial`` q(t) (rad) with continuous second derivative,
fitted through samples of an analytic motion at 200 Hz; the diagram takes q̇ and q̈ from its
derivatives. Every trajectory is checked against the joint position, speed and acceleration
limits before use (:func:`check_limits`), and free-motion kinds also against collisions with
the environment (the motion is scaled down until the tool clears the table and wall).

Kinds (``TrajectoryConfig.kind``; :func:`ftdrake.sim.trajectory_plan.make_trajectory` builds
the one a scenario names):

* ``random``    smooth random waypoints (min-jerk between them) around the home pose.
* ``fourier``   a sum of sines per joint (finite Fourier series, as for dynamic
                identification), faded in and out so the arm starts and ends at rest.
* ``reference`` like the study's: slow, the tool moving mostly in a horizontal plane with
                little Z motion (mostly the S, R and T joints turn).
* ``z_rich``    the same kind of motion with the pitch joints (L, U, B) moving a lot: the
                tool's orientation and height change, exciting Fz and Tz.
* ``contact``   free motion, then the tool tip pressing into the surface ``contact_target``
                by ``press_depth_m`` for ``press_duration_s``, then leaving and moving freely.
* ``rehearsal`` the contact motion holding ``rehearsal_height_m`` above the surface instead
                of pressing: free motion that looks like the task (training data for its
                compensator). Its approach, the contact kind's, still passes 5 mm above.
* ``study``     the study's own motion, from its Table 1: every joint sweeps the study's range
                with the study's mean, slowly (see :func:`study_motion`).
* ``task_covering`` training motion planned for the task: waypoints around the configurations
                the contact scenario passes through on its way to every surface of the task,
                chosen to excite the payload's parameters (:mod:`ftdrake.sim.excitation`).

The contact kinds read the task's geometry from the plant (:class:`RobotGeometry`): the
surface's frame (origin: where to press, z: outward normal) and the tool-tip frame, both named
in ``ScenarioConfig.task``. Nothing of the models' geometry is copied here.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve
from pydrake.trajectories import PiecewisePolynomial
from scipy.optimize import brentq
from scipy.special import gammaln

from ..errors import TrajectoryError

SAMPLE_RATE_HZ = 200.0
FADE_S = 2.0  # fade-in/out of periodic excitations
CONTACT_KINDS = ("contact", "rehearsal")  # the kinds that approach a surface


@dc.dataclass
class JointLimits:
    """Per-joint limits (rad, rad/s, rad/s²)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    names: list[str]

    @classmethod
    def from_plant(cls, plant, instance, acceleration_limit: float) -> JointLimits:
        joints = [plant.get_joint(j) for j in plant.GetJointIndices(instance)]
        joints = [j for j in joints if j.num_positions() == 1]
        return cls(
            lower=np.array([j.position_lower_limits()[0] for j in joints]),
            upper=np.array([j.position_upper_limits()[0] for j in joints]),
            velocity=np.array([j.velocity_upper_limits()[0] for j in joints]),
            acceleration=np.full(len(joints), float(acceleration_limit)),
            names=[j.name() for j in joints],
        )


def check_limits(traj: PiecewisePolynomial, limits: JointLimits, dt: float = 0.005) -> None:
    """Raises TrajectoryError naming the joint, time and value of the first violation."""
    t = _times(traj, dt)
    checks = (
        ("position", traj, limits.lower, limits.upper, "rad"),
        ("velocity", traj.derivative(1), -limits.velocity, limits.velocity, "rad/s"),
        ("acceleration", traj.derivative(2), -limits.acceleration, limits.acceleration, "rad/s²"),
    )
    for what, f, lo, hi, unit in checks:
        values = np.hstack([f.value(ti) for ti in t]).T  # (T, n)
        bad = (values < lo - 1e-9) | (values > hi + 1e-9)
        if bad.any():
            k, j = np.argwhere(bad)[0]
            raise TrajectoryError(
                f"trajectory exceeds the {what} limit of {limits.names[j]} at t = {t[k]:.3f} s: "
                f"{values[k, j]:.4f} {unit} not in [{lo[j]:.4f}, {hi[j]:.4f}]"
            )


# ----------------------------------------------------------------------------------------------
# Free motion.
# ----------------------------------------------------------------------------------------------
# Amplitude (rad) per joint S, L, E, U, R, B, T of the periodic kinds.
_REFERENCE_AMPLITUDE = np.array([0.7, 0.05, 0.12, 0.05, 0.25, 0.06, 0.9])
_Z_RICH_AMPLITUDE = np.array([0.35, 0.3, 0.3, 0.45, 0.8, 0.6, 0.9])
_FOURIER_AMPLITUDE = np.array([0.5, 0.25, 0.4, 0.35, 0.6, 0.45, 0.8])


def _free_motion(config, home_q, limits, robot):
    rng = np.random.default_rng(config.seed)
    n = len(home_q)
    if config.kind == "random":
        motion = _random_waypoints(config, home_q, rng)
    else:
        amplitude = {
            "fourier": _FOURIER_AMPLITUDE,
            "reference": _REFERENCE_AMPLITUDE,
            "z_rich": _Z_RICH_AMPLITUDE,
        }[config.kind][:n]
        base_hz = config.base_frequency_hz * (0.5 if config.kind == "reference" else 1.0)
        motion = _fourier(config.duration_s, home_q, amplitude, base_hz, config.harmonics, rng)
    # Shrink the motion about home until it respects every limit and clears the environment.
    scale = 1.0
    for _ in range(40):
        traj = _spline(lambda t, s=scale: home_q + s * (motion(t) - home_q), config.duration_s)
        if _within_limits(traj, limits, config.speed_fraction) and (
            robot is None or robot.clear_of_environment(traj)
        ):
            return traj
        scale *= 0.85
    raise TrajectoryError(
        f"cannot fit a {config.kind} trajectory within the limits around home_q; "
        "move home_q away from the limits and the environment"
    )


def _fourier(duration, home_q, amplitude, base_hz, harmonics, rng):
    """q(t) = home + fade(t)·A·Σ_l c_l sin(2π l f t + φ_l), Σ|c_l| = 1 per joint."""
    n = len(home_q)
    c = rng.uniform(0.2, 1.0, size=(n, harmonics)) / np.arange(1, harmonics + 1)
    c /= c.sum(axis=1, keepdims=True)
    phase = rng.uniform(0, 2 * np.pi, size=(n, harmonics))
    omega = 2 * np.pi * base_hz * np.arange(1, harmonics + 1)

    def q(t):
        series = (c * np.sin(omega * t + phase)).sum(axis=1)
        return home_q + _fade(t, duration) * amplitude * series

    return q


def _random_waypoints(config, home_q, rng):
    """Min-jerk moves between random waypoints, about 2.5 s apart, ending at home."""
    count = max(2, int(config.duration_s / 2.5))
    spread = _FOURIER_AMPLITUDE[: len(home_q)]
    points = [home_q] + [home_q + rng.uniform(-1, 1, len(home_q)) * spread
                         for _ in range(count - 1)]
    points.append(home_q)
    times = np.linspace(0.0, config.duration_s, len(points))
    return _min_jerk_path(times, np.array(points))


# ----------------------------------------------------------------------------------------------
# The study's motion (Table 1 of the RF-vs-SVR study, Motoman SDA10D).
# ----------------------------------------------------------------------------------------------
#: The study's Table 1 (degrees), joints q1..q7 = S, L, E, U, R, B, T of one SDA10D arm:
#: rows max, min, mean.
STUDY_JOINTS_DEG = np.array([
    [-18.48, -1.80, 179.00, -15.6, -95.30, 100.65, 65.3],
    [-132.70, -103.30, 50.50, -78.00, -116.37, 71.10, 28.10],
    [-88.98, -52.75, 131.41, -52.24, -109.63, 87.40, 48.98],
])
#: The model's configuration (rad) at the study's mean configuration: the default home_q with
#: the shoulder (L) 0.5 rad and the wrist (B) 0.8 rad less bent, the tool axis tilted ~50° from
#: vertical. Chosen (from a small grid of L, U, B offsets) with the study's tool
#: (models/study_tool.sdf) so that the sensor readings come out the size of the study's
#: Table 2, whose Fz (−4.0 … 17.6 N around 6.9 N) says the tool axis swept through horizontal.
STUDY_MODEL_AT_MEAN = np.array([0.0, 0.05, 0.0, 1.45, 0.0, 0.34, 0.0])
#: The study's rows: 13,745 (its Section 5). Its rate is not stated; we assume the ROS
#: joint_states rate of the Motoman driver, ~40 Hz (37 Hz measured in ros-industrial/motoman
#: issue 516), so the study's trajectory lasted 13,745 / 40 = 344 s.
STUDY_SAMPLES = 13745
STUDY_SAMPLE_HZ = 40.0
#: Planned ranges stop this far (deg) inside Table 1's on each side: the controller tracks
#: the study scenario to ~0.15° (experiments.study.protocols.STUDY_KI), and the simulated
#: joints must stay within Table 1. The means are Table 1's.
STUDY_MARGIN_DEG = 0.3
STUDY_DURATION_S = STUDY_SAMPLES / STUDY_SAMPLE_HZ
#: Full cycles of each joint over STUDY_DURATION_S: slow (peak speed 0.09 rad/s, the study's
#: "relatively low velocities and accelerations"), no two neighbours in step.
_STUDY_CYCLES = np.array([2, 3, 2, 3, 4, 3, 5])


def study_to_model(q_study_deg) -> np.ndarray:
    """Study joint angles (deg, SDA10D order S, L, E, U, R, B, T) → the model's (rad).

    The model's zero is the arm straight up; the SDA10D's controller zero and sign conventions
    are not in the study, so the two are aligned at one pose: the study's mean configuration
    (Table 1's µ) is :data:`STUDY_MODEL_AT_MEAN`, and each joint keeps the study's excursion
    about its mean, same sign (the model is built after the SDA10D, joint for joint):
    ``q_model = STUDY_MODEL_AT_MEAN + radians(q_study − µ)``.
    """
    q = np.asarray(q_study_deg, dtype=float)
    return STUDY_MODEL_AT_MEAN + np.radians(q - STUDY_JOINTS_DEG[2])


def model_to_study(q_model) -> np.ndarray:
    """The inverse of :func:`study_to_model`: model angles (rad) → study angles (deg)."""
    q = np.asarray(q_model, dtype=float)
    return STUDY_JOINTS_DEG[2] + np.degrees(q - STUDY_MODEL_AT_MEAN)


def study_motion(duration: float, seed: int) -> PiecewisePolynomial:
    """The study's motion in the model's joints: each joint j sweeps Table 1's [min, max]
    (:data:`STUDY_MARGIN_DEG` inside) ``_STUDY_CYCLES[j]`` times per :data:`STUDY_DURATION_S`
    with Table 1's mean.

    Per joint, ``q = min + (max − min)·s(t)`` with ``u = (1 − cos(ωt + φ))/2`` and ``s = u^p``
    (or ``1 − u^p`` when the mean lies above mid-range); the exponent p makes s's mean over a
    cycle ``Γ(p + ½)/(√π Γ(p + 1))`` equal ``(µ − min)/(max − min)``. Whole cycles: over
    STUDY_DURATION_S each joint's range and mean are Table 1's exactly; a shorter `duration`
    is the start of the same motion. `seed` draws the phases φ, so seeds give different
    trajectories with the same joint statistics (held-out test trajectories).
    """
    hi, lo, mean = np.radians(STUDY_JOINTS_DEG)
    hi, lo = hi - np.radians(STUDY_MARGIN_DEG), lo + np.radians(STUDY_MARGIN_DEG)
    fraction = (mean - lo) / (hi - lo)
    above = fraction > 0.5
    target = np.where(above, 1.0 - fraction, fraction)

    def cycle_mean(p):
        return np.exp(gammaln(p + 0.5) - gammaln(p + 1.0)) / np.sqrt(np.pi)

    power = np.array([brentq(lambda p, m=m: cycle_mean(p) - m, 1e-3, 1e3) for m in target])
    phase = np.random.default_rng(seed).uniform(0.0, 2 * np.pi, len(hi))
    omega = 2 * np.pi * _STUDY_CYCLES / STUDY_DURATION_S
    offset = STUDY_MODEL_AT_MEAN - mean  # study_to_model, in radians

    t = np.linspace(0.0, duration, max(4, round(duration * 10.0) + 1))  # 10 Hz knots: smooth
    u = (1.0 - np.cos(np.outer(omega, t) + phase[:, None])) / 2.0
    s = u ** power[:, None]
    s = np.where(above[:, None], 1.0 - s, s)
    Q = (lo + offset)[:, None] + (hi - lo)[:, None] * s
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, Q, False)


# ----------------------------------------------------------------------------------------------
# The contact scenario.
# ----------------------------------------------------------------------------------------------
#: The contact motion's rest-to-rest moves (s): fast to 5 cm off the surface, slowly to 5 mm
#: off it, then press; after the press up and home. A move whose joints would exceed their
#: speed or acceleration limit in this time takes longer (:func:`_move_durations`).
_MOVES_S = {"approach": 2.0, "descend": 1.0, "touch": 1.0, "ascend": 1.5, "back": 1.5}
#: Peak |q̇|·T/Δq and |q̈|·T²/Δq of a min-jerk move of Δq in T (15/8 and 10/√3).
_MIN_JERK_PEAK_SPEED, _MIN_JERK_PEAK_ACCELERATION = 1.875, 10 / np.sqrt(3)
#: Headroom of a move's duration over the min-jerk bound: the spline through its samples
#: overshoots the analytic peaks a little.
_MOVE_MARGIN = 1.02


def _contact(config, depth, home_q, robot, limits=None):
    """The contact motion, reaching `depth` m into the target surface (< 0: above it). With
    `limits`, each move lasts long enough to stay within the joints' speed and acceleration
    limits (the free motion before it gives up the time); TrajectoryError when that leaves
    less than 2 s of free motion."""
    hover, near, press = robot.press_poses(config.contact_target, depth, home_q)
    waypoints = np.array([home_q, home_q, hover, near, press, press, hover, home_q])
    moves = _move_durations(waypoints, limits)
    for _ in range(4):  # lengthen the moves until the spline through them is within limits
        traj = _contact_spline(config, home_q, waypoints, moves)
        if limits is None or _moves_within(traj, limits):
            break
        moves = {k: v * 1.05 for k, v in moves.items()}
    return traj  # make_trajectory checks its limits


def _move_durations(waypoints, limits) -> dict:
    """Each move's duration: the default, or longer where its min-jerk profile would exceed
    a joint's speed or acceleration limit (with :data:`_MOVE_MARGIN`)."""
    moves = dict(_MOVES_S)
    if limits is None:
        return moves
    # waypoints: home, home, hover, near, press, press, hover, home; the press is not a move.
    steps = {"approach": (1, 2), "descend": (2, 3), "touch": (3, 4), "ascend": (5, 6),
             "back": (6, 7)}
    for name, (a, b) in steps.items():
        dq = np.abs(waypoints[b] - waypoints[a])
        needed = max(float(np.max(_MIN_JERK_PEAK_SPEED * dq / limits.velocity)),
                     float(np.max(np.sqrt(_MIN_JERK_PEAK_ACCELERATION * dq
                                          / limits.acceleration))))
        moves[name] = max(moves[name], _MOVE_MARGIN * needed)
    return moves


def _moves_within(traj, limits) -> bool:
    try:
        check_limits(traj, limits)
        return True
    except TrajectoryError:
        return False


def _contact_spline(config, home_q, waypoints, moves):
    fixed = (moves["approach"] + moves["descend"] + moves["touch"] + config.press_duration_s
             + moves["ascend"] + moves["back"])
    free = config.duration_s - fixed
    if free < 2.0:
        raise TrajectoryError(
            f"trajectory.duration_s: {config.duration_s} s leaves {free:.1f} s of free motion "
            f"before the press (its moves take {fixed - config.press_duration_s:.1f} s within "
            f"the joints' limits); need at least {fixed + 2.0:.1f} s"
        )
    rng = np.random.default_rng(config.seed)
    # Short free phases fade in and out faster, so their amplitude shrinks with (free / 4 s)².
    amplitude = 0.5 * _REFERENCE_AMPLITUDE[: len(home_q)] * min(1.0, (free / 4.0) ** 2)
    wiggle = _fourier(free, home_q, amplitude, 0.15, 2, rng)
    times = np.cumsum([0, free, moves["approach"], moves["descend"], moves["touch"],
                       config.press_duration_s, moves["ascend"], moves["back"]])
    path = _min_jerk_path(times[1:], waypoints[1:])

    def q(t):
        return wiggle(t) if t < free else path(t)

    return _spline(q, config.duration_s)


class RobotGeometry:
    """Kinematic queries on the scene's plant: IK for the press and clearance checks.

    The task's geometry comes from the plant's frames that ``scene.task`` names, looked up when
    first needed (a free-motion scenario needs neither a tool tip nor a surface): the tool tip
    as ``X_STip`` (fixed: the tip is on the sensor's tool side) and each surface as its point
    and outward normal in W (fixed: the surface is welded to the world).
    """

    def __init__(self, diagram, plant, scene_graph, scene):
        self._diagram = diagram
        self._plant = plant
        self._scene = scene
        self._context = diagram.CreateDefaultContext()
        self._plant_context = plant.GetMyMutableContextFromRoot(self._context)
        self._sg_context = scene_graph.GetMyContextFromRoot(self._context)
        self._query_port = scene_graph.get_query_output_port()
        self._X_STip = None

    def tool_tip(self) -> tuple[np.ndarray, np.ndarray]:
        """``(p_STip, z_Tip_S)``: the tool tip's position (m) and the tool axis (unit, out of
        the tip), in the sensor frame S, from the frame ``task.tool_tip_frame``."""
        if self._X_STip is None:
            tip, S = self._scene.tool_tip_frame(), self._scene.sensor_frame
            if tip.body().index() == S.body().index():  # composed exactly from fixed offsets
                X_BS, X_BTip = S.GetFixedPoseInBodyFrame(), tip.GetFixedPoseInBodyFrame()
                self._X_STip = X_BS.InvertAndCompose(X_BTip)
            else:  # on a body welded to S's: the same pose at every configuration
                self._X_STip = tip.CalcPose(self._plant_context, S)
        return self._X_STip.translation().copy(), self._X_STip.rotation().matrix()[:, 2].copy()

    def surface(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``(p_WSurface, n_W)``: the point to press on surface `name` (a key of
        ``task.surfaces``) and its outward unit normal, in W, from that surface's frame."""
        frame = self._scene.surface_frame(name)
        X_WF = frame.CalcPoseInWorld(self._plant_context)  # welded to W: any q will do
        return X_WF.translation().copy(), X_WF.rotation().matrix()[:, 2].copy()

    @property
    def plant(self):
        """The plant the queries run on."""
        return self._plant

    @property
    def arm(self):
        """The arm's model instance in `plant`."""
        return self._scene.arm

    @property
    def sensor_frame(self):
        """Frame S, the sensor's, in `plant`."""
        return self._scene.sensor_frame

    def surfaces(self) -> list[str]:
        """The task's surface names (``task.surfaces``' keys), in their order."""
        return list(self._scene.task.surfaces)

    def clear_at(self, q, margin: float = 0.02) -> bool:
        """True if the robot at arm configuration `q` is `margin` m away from the
        environment."""
        self._plant.SetPositions(self._plant_context, self._scene.arm, np.asarray(q, float))
        query = self._query_port.Eval(self._sg_context)
        return all(pair.distance >= margin
                   for pair in query.ComputeSignedDistancePairwiseClosestPoints(margin))

    def tip_and_axis(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Tool tip position (m) and tool axis (the tip frame's z), both in W, at arm
        configuration q."""
        p_STip, z_Tip_S = self.tool_tip()
        self._plant.SetPositions(self._plant_context, self._scene.arm, q)
        X_WS = self._scene.sensor_frame.CalcPoseInWorld(self._plant_context)
        return X_WS @ p_STip, X_WS.rotation() @ z_Tip_S

    def clear_of_environment(self, traj, dt: float = 0.05, margin: float = 0.02) -> bool:
        """True if the robot stays `margin` m away from the environment along `traj`."""
        return all(self.clear_at(traj.value(t).ravel(), margin) for t in _times(traj, dt))

    def press_poses(self, target: str, depth: float, home_q):
        """Configurations with the tool tip 5 cm and 5 mm off surface `target`, and `depth`
        into it (the controller's stiffness turns that depth into the pressing force)."""
        surface, normal = self.surface(target)
        axis_W = -normal  # the tool points into the surface
        hover = self._solve_ik(surface + 0.05 * normal, axis_W, home_q)
        near = self._solve_ik(surface + 0.005 * normal, axis_W, hover)
        press = self._solve_ik(surface - depth * normal, axis_W, near)
        return hover, near, press

    def _solve_ik(self, p_WTip, axis_W, q_guess):
        plant = self._plant
        ik = InverseKinematics(plant, with_joint_limits=True)
        S = self._scene.sensor_frame
        p_STip, z_Tip_S = self.tool_tip()
        ik.AddPositionConstraint(S, p_STip, plant.world_frame(), p_WTip - 5e-4, p_WTip + 5e-4)
        ik.AddAngleBetweenVectorsConstraint(S, z_Tip_S, plant.world_frame(), axis_W, 0, 0.02)
        arm_q = ik.q()  # the plant's only free joints are the arm's
        prog = ik.get_mutable_prog()
        prog.AddQuadraticErrorCost(np.eye(len(q_guess)), np.asarray(q_guess), arm_q)
        prog.SetInitialGuess(arm_q, q_guess)
        result = Solve(prog)
        if not result.is_success():
            raise TrajectoryError(
                f"no arm configuration puts the tool tip at {np.round(p_WTip, 3).tolist()} "
                f"pointing along {axis_W.tolist()}"
            )
        return result.GetSolution(arm_q)


# ----------------------------------------------------------------------------------------------
# Helpers.
# ----------------------------------------------------------------------------------------------
def _spline(q_of_t, duration: float) -> PiecewisePolynomial:
    t = np.linspace(0.0, duration, max(4, round(duration * SAMPLE_RATE_HZ) + 1))
    Q = np.column_stack([q_of_t(ti) for ti in t])
    zero = np.zeros((Q.shape[0], 1))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, Q, zero, zero)


def _min_jerk_path(times, points):
    """Rest-to-rest min-jerk moves through `points` at `times`."""

    def q(t):
        k = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2))
        s = np.clip((t - times[k]) / (times[k + 1] - times[k]), 0.0, 1.0)
        return points[k] + (points[k + 1] - points[k]) * (10 * s**3 - 15 * s**4 + 6 * s**5)

    return q


def _fade(t, duration):
    """0 → 1 over FADE_S at the start and 1 → 0 at the end, C² smooth."""
    def smoothstep(s):
        s = np.clip(s, 0.0, 1.0)
        return 10 * s**3 - 15 * s**4 + 6 * s**5
    fade = min(FADE_S, duration / 3)
    return smoothstep(t / fade) * smoothstep((duration - t) / fade)


def _within_limits(traj, limits, speed_fraction) -> bool:
    try:
        scaled = dc.replace(limits, velocity=limits.velocity * speed_fraction)
        check_limits(traj, scaled, dt=0.02)
        return True
    except TrajectoryError:
        return False


def _times(traj, dt):
    return np.arange(traj.start_time(), traj.end_time() + 1e-12, dt)


def trajectory_extent(traj, robot: RobotGeometry, dt: float = 0.05) -> dict:
    """Tool-tip min/max/mean/std per axis along `traj` (m), like the study's Table 3, plus
    ``tilt``: the angle (rad) between the tool axis z_S and straight down."""
    samples = [robot.tip_and_axis(traj.value(t).ravel()) for t in _times(traj, dt)]
    tips = np.array([tip for tip, _ in samples])
    tilt = np.arccos(np.clip([-axis[2] for _, axis in samples], -1.0, 1.0))
    table = {axis: tips[:, i] for i, axis in enumerate("xyz")}
    table["tilt"] = tilt
    return {
        name: {"max": float(v.max()), "min": float(v.min()), "mean": float(v.mean()),
               "std": float(v.std())}
        for name, v in table.items()
    }


__all__ = [
    "CONTACT_KINDS",
    "STUDY_DURATION_S",
    "STUDY_JOINTS_DEG",
    "STUDY_SAMPLE_HZ",
    "JointLimits",
    "RobotGeometry",
    "TrajectoryError",
    "check_limits",
    "model_to_study",
    "study_motion",
    "study_to_model",
    "trajectory_extent",
]
