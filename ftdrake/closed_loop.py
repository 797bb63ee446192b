"""The compensator and contact detector in the loop of the simulated arm, evaluated against
the plant's ground truth.

    noisy sensor ── wrench_measured ──► CompensatorSystem ── wrench_external ──► ContactDetector
    plant ───────── joint_state ─────►        │ wrench_std ─────────────────────►
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from pydrake.geometry import Cylinder, Rgba
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import LeafSystem
from pydrake.systems.primitives import LogVectorOutput

from . import columns as col
from .config import ScenarioConfig
from .diagram import build_diagram
from .simulation import run
from .systems import CompensatorSystem, ContactDetector, DetectorConfig

PREDICTED, ESTIMATED = "pred", "est_external"


def add_compensation(model, detector_config: DetectorConfig, meshcat=None):
    """An `extra` hook for build_diagram: wires compensator, detector, loggers (and arrows)."""

    def extra(builder, parts):
        scene, noisy, period = parts["scene"], parts["noisy_sensor"], parts["period"]
        plant = scene.plant
        comp = builder.AddNamedSystem(
            "compensator",
            CompensatorSystem(model, period, n_joints=plant.num_positions(scene.arm)),
        )
        builder.Connect(noisy.GetOutputPort("wrench_measured"), comp.GetInputPort("wrench_measured"))
        builder.Connect(plant.get_state_output_port(scene.arm), comp.GetInputPort("joint_state"))
        detector = builder.AddNamedSystem("contact_detector", ContactDetector(detector_config, period))
        builder.Connect(comp.GetOutputPort("wrench_external"), detector.GetInputPort("wrench_external"))
        builder.Connect(comp.GetOutputPort("wrench_std"), detector.GetInputPort("wrench_std"))
        loggers = {
            name: LogVectorOutput(system.GetOutputPort(name), builder, period)
            for system, name in (
                (comp, "wrench_internal"), (comp, "wrench_external"), (comp, "wrench_std"),
                (comp, "out_of_domain"), (comp, "fault"), (detector, "contact"),
                (detector, "contact_force"),
            )
        }
        if meshcat is not None:
            arrows = builder.AddNamedSystem("wrench_arrows", WrenchArrows(meshcat, plant, scene))
            builder.Connect(noisy.GetOutputPort("wrench_measured"), arrows.GetInputPort("measured"))
            builder.Connect(comp.GetOutputPort("wrench_external"), arrows.GetInputPort("external"))
            builder.Connect(plant.get_body_poses_output_port(), arrows.GetInputPort("body_poses"))
        return {"compensator": comp, "detector": detector, "loggers": loggers}

    return extra


def run_closed_loop(config: ScenarioConfig, model, detector_config: DetectorConfig, *,
                    meshcat=None, progress=True):
    """Simulates `config` with compensation in the loop; returns (log, timing summary)."""
    sim = build_diagram(config, extra=add_compensation(model, detector_config, meshcat),
                        meshcat=meshcat)
    log, timing = run(sim, progress=progress)
    return append_compensation_log(sim, log), timing


def append_compensation_log(sim, log: pd.DataFrame, root_context=None) -> pd.DataFrame:
    """Adds the compensator and detector outputs to `log` (same sample times)."""
    context = root_context or sim.simulator.get_context()
    loggers = sim.builder_extras["loggers"]
    t = log[col.TIME].to_numpy()

    def values(name):
        data = loggers[name].FindLog(context)
        times, v = data.sample_times(), data.data().T
        keep = times > 0.5 * sim.config.time_step
        if not np.allclose(times[keep], t):
            raise RuntimeError(f"logger {name!r} is not sampled with the log")
        return v[keep]

    extra = {}
    for prefix, name in ((PREDICTED, "wrench_internal"), (ESTIMATED, "wrench_external"),
                         ("pred_std", "wrench_std")):
        extra.update(zip(col.wrench_columns(prefix), values(name).T))
    extra["out_of_domain"] = values("out_of_domain")[:, 0].astype(np.int8)
    extra["fault"] = values("fault")[:, 0].astype(np.int8)
    extra["detected"] = values("contact")[:, 0].astype(np.int8)
    extra["detected_force"] = values("contact_force")[:, 0]
    return pd.concat([log, pd.DataFrame(extra, index=log.index)], axis=1)


# ----------------------------------------------------------------------------------------------
STARTUP_SAMPLES = 2  # the sensor chain reads the plant's pre-step zero for this many samples
TOUCHDOWN_S = 0.02  # s after each contact onset left out of the "after touchdown" error


def evaluate_detection(log: pd.DataFrame, noise_std) -> dict:
    """Detection and compensation quality against the plant's ground truth.

    * detection_delay_s: per true contact episode, first detection minus true onset (a
      detection within 0.5 s before the onset counts as early, delay < 0).
    * false_positives: detection onsets that do not overlap any true contact (± 0.5 s).
    * missed_contacts: true contact episodes with no detection during them.
    * external_wrench_error_rms: RMS of estimated − true external wrench while in contact;
      ..._after_touchdown: the same without the first TOUCHDOWN_S of each contact, where a
      millisecond-long impact spike, seen one sample late, dominates the RMS.
    * compensation_error_rms: RMS of predicted − true internal wrench in free motion, and
      that over the sensor noise σ (compensation_error_over_noise). The first
      STARTUP_SAMPLES rows are excluded (reported as excluded_startup_samples): before the
      plant's first step its sampled outputs read zero, and the compensator, one sample behind
      the sensor, sees that zero as a measurement.
    """
    t = log[col.TIME].to_numpy()
    truth = log[col.CONTACT].to_numpy().astype(bool)
    detected = log["detected"].to_numpy().astype(bool)
    true_eps, det_eps = _episodes(truth), _episodes(detected)
    margin = 0.5
    delays, missed = [], 0
    for a, b in true_eps:
        hits = [s for s, e in det_eps if t[s] <= t[b - 1] and t[e - 1] >= t[a] - margin]
        if hits:
            delays.append(float(t[min(hits)] - t[a]))
        else:
            missed += 1
    false_pos = sum(
        1 for s, e in det_eps
        if not any(t[s] <= t[b - 1] + margin and t[e - 1] >= t[a] - margin for a, b in true_eps)
    )
    free = ~truth
    free[:STARTUP_SAMPLES] = False
    pred = log[col.wrench_columns(PREDICTED)].to_numpy()
    internal = log[col.wrench_columns(col.INTERNAL)].to_numpy()
    comp_rms = np.sqrt(np.mean((pred[free] - internal[free]) ** 2, axis=0))
    est = log[col.wrench_columns(ESTIMATED)].to_numpy()
    ext = log[col.wrench_columns(col.EXTERNAL)].to_numpy()
    ext_rms = (np.sqrt(np.mean((est[truth] - ext[truth]) ** 2, axis=0))
               if truth.any() else np.full(6, np.nan))
    steady = truth.copy()
    for a, _ in true_eps:  # the touchdown transient: a spike the compensator sees 1 sample late
        steady[(t >= t[a]) & (t < t[a] + TOUCHDOWN_S)] = False
    steady_rms = (np.sqrt(np.mean((est[steady] - ext[steady]) ** 2, axis=0))
                  if steady.any() else np.full(6, np.nan))
    return {
        "true_contacts": len(true_eps),
        "detected_contacts": len(det_eps),
        "detection_delay_s": delays[0] if len(delays) == 1 else (delays or None),
        "false_positives": int(false_pos),
        "missed_contacts": int(missed),
        "external_wrench_error_rms": ext_rms.tolist(),
        "external_wrench_error_rms_after_touchdown": steady_rms.tolist(),
        "compensation_error_rms": comp_rms.tolist(),
        "compensation_error_over_noise": (comp_rms / np.asarray(noise_std)).tolist(),
        "out_of_domain_fraction": float(log["out_of_domain"].mean()),
        "fault_samples": int(log["fault"].sum()),
        "excluded_startup_samples": STARTUP_SAMPLES,
    }


def _episodes(flags: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of runs of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2]))


# ----------------------------------------------------------------------------------------------
class WrenchArrows(LeafSystem):
    """Draws the measured (grey) and compensated external (red) force as arrows at So.

    Input ports: measured (6), external (6), body_poses (abstract). Publishes at 30 Hz;
    with Meshcat recording on, the arrows are part of the replay. Scale: 1 cm per N.
    """

    SCALE_M_PER_N = 0.01

    def __init__(self, meshcat, plant, scene):
        super().__init__()
        from pydrake.common.value import AbstractValue

        self._meshcat = meshcat
        self._body = int(scene.sensor_frame.body().index())
        self._X_BS = scene.sensor_frame.GetFixedPoseInBodyFrame()
        self.DeclareVectorInputPort("measured", 6)
        self.DeclareVectorInputPort("external", 6)
        self.DeclareAbstractInputPort("body_poses",
                                      AbstractValue.Make([RigidTransform()] * plant.num_bodies()))
        for name, rgba in (("measured", Rgba(0.4, 0.4, 0.4, 0.9)), ("external", Rgba(0.9, 0.1, 0.1, 1))):
            meshcat.SetObject(f"wrench/{name}", Cylinder(0.006, 1.0), rgba)
        self.DeclarePeriodicPublishEvent(1 / 30, 0.0, self._draw)

    def _draw(self, context):
        X_WS = self.get_input_port(2).Eval(context)[self._body] @ self._X_BS
        for index, name in ((0, "measured"), (1, "external")):
            f_S = self.get_input_port(index).Eval(context)[:3]
            f_W = X_WS.rotation() @ f_S
            length = max(1e-4, np.linalg.norm(f_W) * self.SCALE_M_PER_N)
            R = _rotation_z_to(f_W)
            X = RigidTransform(R, X_WS.translation() + R.col(2) * length / 2)
            path = f"wrench/{name}"
            self._meshcat.SetTransform(path, X, context.get_time())
            self._meshcat.SetProperty(path, "scale", [1.0, 1.0, length], context.get_time())


def _rotation_z_to(v) -> RotationMatrix:
    n = np.linalg.norm(v)
    if n < 1e-12:
        return RotationMatrix()
    return RotationMatrix.MakeFromOneVector(np.asarray(v) / n, 2)
