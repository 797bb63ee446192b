"""The product: what runs beside the robot, in simulation and live.

:class:`CompensationChain` (``chain``) wires the :class:`CompensatorSystem` (``compensator``),
the :class:`OnlineBiasTracker` (``bias_tracker``) and the :class:`ContactDetector`
(``detector``), with :class:`JointStateGravity` (``joint_gravity``) for the tracker's payload
estimate on a robot without a plant, and :class:`DelayLine` (``delay_line``) corrects a delay
between the joint-state and wrench streams. :func:`add_recorder` (``recorder``; not imported
by this package, as it reads the column names of :mod:`ftdrake.offline.replay`) logs any
diagram in the layout replay reads.
``sim.station`` and ``hardware.station`` both add the chain; nothing here imports the
simulation rig (``systems``, ``sim``).
"""

from .bias_tracker import OnlineBiasTracker
from .chain import CompensationChain
from .compensator import CompensatorSystem
from .delay_line import DelayLine
from .detector import ContactDetector
from .joint_gravity import JointStateGravity

__all__ = [
    "CompensationChain",
    "CompensatorSystem",
    "ContactDetector",
    "DelayLine",
    "JointStateGravity",
    "OnlineBiasTracker",
]
