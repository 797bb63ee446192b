"""LiveConfig: a live robot's config file — the product's chain and its transport.

    chain: {compensator: ..., bias_tracker: ..., detector: ..., sensor: ..., robot: ...}
    lcm: {joint_state_channel: ..., ft_channel: ...}      # HardwareConfig (serve on LCM)
    ros2: {joint_names: [...], wrench_topic: ...}          # Ros2Config (serve --ros2)

:func:`load_live_config` reads it (any of the three sections may be left out: its defaults); a
file with only the chain's sections at its top (a
:class:`~ftdrake.config.ChainConfig`) is read as ``chain:`` alone, and a scenario file, until
the next release, for its chain (:func:`~ftdrake.config.load_chain_config`, with a warning).
Each section is validated where it is used: the chain when loaded, a transport when a station
opens it (a ROS 2 section needs the model's joint names, an LCM-only file has none).
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types.
import dataclasses as dc
from pathlib import Path

from ..config import ChainConfig, load_chain_config, parse_config
from ..config.files import read_mapping
from .config import HardwareConfig
from .ros2.config import Ros2Config


@dc.dataclass
class LiveConfig:
    """The chain (:class:`~ftdrake.config.ChainConfig`) and the transports of a live robot:
    ``lcm`` (:class:`~ftdrake.hardware.config.HardwareConfig`) and ``ros2``
    (:class:`~ftdrake.hardware.ros2.config.Ros2Config`)."""

    chain: ChainConfig = dc.field(default_factory=ChainConfig)
    lcm: HardwareConfig = dc.field(default_factory=HardwareConfig)
    ros2: Ros2Config = dc.field(default_factory=Ros2Config)

    def validate(self) -> "LiveConfig":
        """Validates the chain (the transports: by the station that opens one)."""
        self.chain.validate()
        return self


def load_live_config(path: "str | Path | None") -> LiveConfig:
    """The LiveConfig of `path` (see the module); None: the defaults. Its chain is validated
    (errors name ``chain.<field>``); the transports are validated by the station that uses
    them."""
    if path is None:
        return LiveConfig()
    data = read_mapping(Path(path))
    sections = {f.name for f in dc.fields(LiveConfig)}
    if data and set(data) <= sections:  # chain:, lcm:, ros2: (any of them)
        return parse_config(Path(path).read_text(), LiveConfig, source=str(path))
    return LiveConfig(chain=load_chain_config(path))  # a chain file, or a scenario (it warns)
