"""Data files: datasets ftdrake writes, and robot logs (tables, ROS bags) it reads.

* :mod:`.dataset` – ``collect``'s Parquet datasets (scenario in the metadata).
* :mod:`.logs` – tables (CSV/Parquet) into a validated :class:`RobotLog`; the checks every
  reader shares.
* :mod:`.bag` – ROS 1 / ROS 2 bags into a :class:`RobotLog`.
* :mod:`.training` – :func:`load_training_data`: any log into ``X = [q, q̇, q̈]`` and targets,
  read as one :class:`ReadOptions` says (shared by ``train``, ``evaluate``, study and demo).
"""

from .bag import read_bag
from .dataset import joint_state_layout, load_dataset, save_dataset, wrench_targets
from .logs import LogWarning, RobotLog, expand_columns, read_frame, read_table
from .training import ReadOptions, TrainingData, load_training_data

__all__ = [
    "LogWarning",
    "ReadOptions",
    "RobotLog",
    "TrainingData",
    "expand_columns",
    "joint_state_layout",
    "load_dataset",
    "load_training_data",
    "read_bag",
    "read_frame",
    "read_table",
    "save_dataset",
    "wrench_targets",
]
