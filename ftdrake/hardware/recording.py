"""LCM log (lcm-logger / lcm.EventLog) → the table layout ``collect`` writes, as Parquet.

Rows: one per F/T message (the sensor rate, as in ``collect``): ``t`` (the F/T message's
timestamp, s), ``q_i``, ``qd_i`` from the latest joint-state message whose timestamp is
≤ t and within `tolerance_s` (pandas ``merge_asof``, backward: a causal match, what the
live station uses), ``meas_Fx..meas_Tz``. With ``joint_state_type: robot_state``, positions and
velocities (``velocity_channel``) with the same utime form one joint sample; a half without
its partner is counted in ``unpaired``. F/T rows with no such joint sample are not
written but counted in the report (``unmatched_ft``), as are joint messages no F/T row used
(``unused_joint``) and messages that failed to decode (``malformed``). Needs the ``lcm``
package (``lcm>=1.5,<2``) for ``EventLog``; ``ftdrake record`` feeds live messages to
:func:`table_from_messages` instead.
"""

from __future__ import annotations

import struct

import numpy as np
import pandas as pd

from ..conventions import MEASURED, QD, TIME, Q, joint_columns, wrench_columns
from ..errors import LogError
from .config import HardwareConfig
from .live_inputs import RobotStatePairer
from .messages import decode_joint_state, decode_wrench


def read_lcm_log(path, config: HardwareConfig, tolerance_s: float = 0.002):
    """Reads an lcm-logger file. Returns (table, report)."""
    import lcm  # noqa: PLC0415 (lcm only to read lcm-logger files)

    try:
        log = lcm.EventLog(str(path), "r")
    except OSError as e:
        raise LogError(f"{path}: cannot read the LCM log: {e}") from None
    return table_from_messages(((e.channel, e.data) for e in log), config, tolerance_s,
                               source=str(path))


def table_from_messages(messages, config: HardwareConfig, tolerance_s: float = 0.002,
                        source: str = "LCM messages"):
    """(channel, bytes) pairs in arrival order → (table, report); other channels ignored."""
    n = config.n_joints
    joints, wrenches, malformed, unpaired, wrong_count = [], [], 0, 0, 0
    pairer = (RobotStatePairer(max_pending=10**9) if config.joint_state_type == "robot_state"
              else None)
    halves = {config.joint_state_channel: "q", config.velocity_channel: "v"}
    for channel, data in messages:
        try:
            if channel == config.ft_channel:
                w = decode_wrench(data)
                wrenches.append(np.r_[w.t, w.wrench])
                continue
            if channel not in halves or (pairer is None and channel != config.joint_state_channel):
                continue
            s = decode_joint_state(config.joint_state_type, data)
            if pairer is not None:
                s = pairer.add(halves[channel], s)
                unpaired += len(pairer.dropped)
                pairer.dropped.clear()
                if s is None:
                    continue
            if len(s.q) != n or s.v is None or len(s.v) != n:
                wrong_count += 1
                continue
            joints.append(np.r_[s.t, s.q, s.v])
        except (ValueError, struct.error):
            malformed += 1
    if pairer is not None:  # halves still waiting at the end
        unpaired += pairer.waiting()
    extra = {"joint_count": wrong_count} if wrong_count else {}
    if pairer is not None:
        extra["unpaired"] = unpaired
    return table_from_samples(joints, wrenches, n, tolerance_s, source,
                              (config.ft_channel, config.joint_state_channel),
                              malformed=malformed, **extra)


def table_from_samples(joints, wrenches, n: int, tolerance_s: float = 0.002,
                       source: str = "messages", names=("F/T", "joint-state"), **counts):
    """Decoded samples → (table, report): `joints` rows ``[t, q (n), v (n)]``, `wrenches`
    rows ``[t, wrench (6)]``, in any order; each F/T row takes the latest joint sample at or
    before its time within `tolerance_s` (see the module). `names` (F/T, joint) name the
    streams in the error; `counts` are added to the report after its own counts."""
    if not wrenches or not joints:
        raise LogError(f"{source}: no {names[0]} or {names[1]} messages with the configured "
                       "joint count")
    jcols = [TIME, *joint_columns(Q, n), *joint_columns(QD, n)]
    jt = pd.DataFrame(np.array(joints), columns=jcols).sort_values(TIME, kind="stable")
    jt["_joint_index"] = np.arange(len(jt))
    ft = pd.DataFrame(np.array(wrenches), columns=[TIME, *wrench_columns(MEASURED)])
    ft = ft.sort_values(TIME, kind="stable")
    merged = pd.merge_asof(ft, jt, on=TIME, direction="backward", tolerance=tolerance_s)
    matched = merged["_joint_index"].notna()
    table = merged[matched].drop(columns="_joint_index")
    table = table[[TIME, *joint_columns(Q, n), *joint_columns(QD, n), *wrench_columns(MEASURED)]]
    used = set(merged.loc[matched, "_joint_index"].astype(int))
    report = {"ft": len(ft), "joint": len(jt), "rows": int(matched.sum()),
              "unmatched_ft": int((~matched).sum()), "unused_joint": len(jt) - len(used),
              **counts}
    return table.reset_index(drop=True), report


def write_table(table, out_path) -> None:
    """Writes a recorded table as Parquet, atomically, stamped with the log format
    (:func:`ftdrake.data.logs.write_log`)."""
    from ..data.logs import write_log  # noqa: PLC0415 (the log readers only to write one)

    write_log(table, out_path)


def record_to_parquet(log_path, out_path, config: HardwareConfig, tolerance_s: float = 0.002):
    """read_lcm_log, then writes Parquet atomically. Returns the report."""
    table, report = read_lcm_log(log_path, config, tolerance_s)
    write_table(table, out_path)
    return report
