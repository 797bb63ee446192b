"""A cable/hose dragging on the tool: the configuration-dependent force rigid models miss."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.framework import LeafSystem

from .config import CableConfig

_SOFTPLUS_WIDTH = 0.01  # m: the cable goes from slack to taut over about this length


class CableForce(LeafSystem):
    """Force of a cable running from a point on the forearm to a point on the tool.

    Input ports:
      state (plant q, v): the plant's state output port.
    Output ports:
      spatial_forces (abstract, list of ExternallyAppliedSpatialForce): one force on the
        sensor's child (tool) body at the cable's attachment point, expressed in W. Connect to
        the plant's ``get_applied_spatial_force_input_port()``.

    The force is a tension ``stiffness · softplus(‖d‖ − rest_length)`` along ``d`` (attachment
    → anchor) plus ``weight_n`` pulling straight down: it depends on the configuration, so the
    sensor reads it and a tool-only payload model cannot explain it.
    """

    def __init__(self, plant, sensor_frame, config: CableConfig):
        super().__init__()
        config.validate()
        self._config = config
        self._plant = plant
        self._plant_context = plant.CreateDefaultContext()
        self._anchor_frame = plant.GetBodyByName(config.anchor_body).body_frame()
        self._tool_body = sensor_frame.body()
        # The attachment point, given in S, re-expressed in the tool body's frame.
        X_BS = sensor_frame.GetFixedPoseInBodyFrame()
        self._p_BoAttach_B = X_BS @ np.asarray(config.p_SAttach, dtype=float)
        self._p_AnchorBody = np.asarray(config.p_anchor, dtype=float).reshape(3, 1)
        self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self.DeclareAbstractOutputPort(
            "spatial_forces", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            self._calc, prerequisites_of_calc={self.all_input_ports_ticket()},
        )

    def force_W(self, q: np.ndarray) -> np.ndarray:
        """The cable's force on the tool (N, in W) at configuration `q` (full plant q)."""
        self._plant.SetPositions(self._plant_context, q)
        world = self._plant.world_frame()
        p_WAnchor = self._plant.CalcPointsPositions(
            self._plant_context, self._anchor_frame, self._p_AnchorBody, world
        ).ravel()
        p_WAttach = self._plant.CalcPointsPositions(
            self._plant_context, self._tool_body.body_frame(),
            self._p_BoAttach_B.reshape(3, 1), world,
        ).ravel()
        d = p_WAnchor - p_WAttach
        length = np.linalg.norm(d)
        stretch = (length - self._config.rest_length) / _SOFTPLUS_WIDTH
        tension = self._config.stiffness * _SOFTPLUS_WIDTH * np.logaddexp(0.0, stretch)
        return tension * d / length + np.array([0.0, 0.0, -self._config.weight_n])

    def _calc(self, context, output):
        if not self._config.enabled:
            output.set_value([])
            return
        x = self.get_input_port().Eval(context)
        force = ExternallyAppliedSpatialForce()
        force.body_index = self._tool_body.index()
        force.p_BoBq_B = self._p_BoAttach_B
        force.F_Bq_W = SpatialForce(tau=np.zeros(3), f=self.force_W(x[: self._plant.num_positions()]))
        output.set_value([force])
