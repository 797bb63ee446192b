"""WrenchArrows: the measured and compensated force drawn as arrows in Meshcat; and
:func:`recording_meshcat`, the Meshcat a replay file is recorded with."""

from __future__ import annotations

import logging

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Cylinder, Meshcat, MeshcatParams, Rgba
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import LeafSystem


class WrenchArrows(LeafSystem):
    """Draws the measured (grey) and compensated external (red) force as arrows at So.

    Input ports: measured (6), external (6), body_poses (abstract). Publishes at 30 Hz;
    with Meshcat recording on, the arrows are part of the replay. Scale: 1 cm per N.
    """

    SCALE_M_PER_N = 0.01

    def __init__(self, meshcat, plant, scene):
        super().__init__()
        self._meshcat = meshcat
        self._body = int(scene.sensor_frame.body().index())
        self._X_BS = scene.sensor_frame.GetFixedPoseInBodyFrame()
        self.DeclareVectorInputPort("measured", 6)
        self.DeclareVectorInputPort("external", 6)
        self.DeclareAbstractInputPort("body_poses",
                                      AbstractValue.Make([RigidTransform()] * plant.num_bodies()))
        for name, rgba in (("measured", Rgba(0.4, 0.4, 0.4, 0.9)),
                           ("external", Rgba(0.9, 0.1, 0.1, 1))):
            meshcat.SetObject(f"wrench/{name}", Cylinder(0.006, 1.0), rgba)
        self.DeclarePeriodicPublishEvent(1 / 30, 0.0, self._draw)

    def get_input_port_measured(self):
        return self.GetInputPort("measured")

    def get_input_port_external(self):
        return self.GetInputPort("external")

    def get_input_port_body_poses(self):
        return self.GetInputPort("body_poses")

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


def recording_meshcat() -> Meshcat:
    """A Meshcat to record a run into a self-contained replay file (``StaticHtml``): on the
    loopback, on any free port, without Drake's "Meshcat listening for connections at
    http://…" line. Nothing is meant to connect to it, and its server ends with the process,
    so that address would lead nowhere."""
    params = MeshcatParams()
    params.host, params.port = "localhost", 0  # loopback; any free port
    drake = logging.getLogger("drake")
    level = drake.level
    drake.setLevel(logging.WARNING)
    try:
        return Meshcat(params)
    finally:
        drake.setLevel(level)
