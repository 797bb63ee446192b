"""The product: what runs beside the robot, in simulation and live.

:class:`CompensationChain` (``chain``) wires the :class:`CompensatorSystem` (``compensator``),
the :class:`OnlineBiasTracker` (``bias_tracker``) and the :class:`ContactDetector`
(``detector``), with :class:`JointStateGravity` (``joint_gravity``) for the tracker's payload
estimate on a robot without a plant. ``sim.station`` and ``hardware.station`` both add the
chain; nothing here imports the simulation rig (``systems``, ``sim``).
"""

from .bias_tracker import OnlineBiasTracker
from .chain import CompensationChain
from .compensator import CompensatorSystem
from .detector import ContactDetector
from .joint_gravity import JointStateGravity

__all__ = [
    "CompensationChain",
    "CompensatorSystem",
    "ContactDetector",
    "JointStateGravity",
    "OnlineBiasTracker",
]
