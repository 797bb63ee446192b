"""The product: what runs beside the robot, in simulation and live.

:class:`CompensationChain` (``chain``) wires the :class:`CompensatorSystem` (``compensator``),
the :class:`OnlineBiasTracker` (``bias_tracker``) and the :class:`ContactDetector`
(``detector``), with :class:`JointStateGravity` (``joint_gravity``) for the tracker's payload
estimate on a robot without a plant, and :class:`DelayLine` (``delay_line``) corrects a delay
between the joint-state and wrench streams. ``sim.station`` and ``hardware.station`` both add
the chain; nothing here imports the simulation rig (``systems``, ``sim``) or the tools around
it (``offline``: replay, the recorder, thresholds).
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
