"""LCM log (lcm-logger / lcm.EventLog) → the table layout ``collect`` writes, as Parquet.

Rows: one per F/T message (the sensor rate, as in ``collect``): ``t`` (the F/T message's
timestamp, s), ``q_i``, ``qd_i`` from the latest joint-state message whose timestamp is
≤ t and within `tolerance_s` (pandas ``merge_asof``, backward: a causal match, what the
live station uses), ``meas_Fx..meas_Tz``. F/T rows with no such joint sample are not
written but counted in the report (``unmatched_ft``), as are joint messages no F/T row used
(``unused_joint``) and messages that failed to decode (``malformed``). Needs the ``lcm``
package (``lcm>=1.5,<2``) for ``EventLog``.
"""

from __future__ import annotations

import struct

import numpy as np
import pandas as pd

from ftdrake import LogError
from ftdrake.conventions import MEASURED, QD, TIME, Q, joint_columns, wrench_columns
from ftdrake.io import atomic_path

from .config import HardwareConfig
from .messages import decode_joint_state, decode_wrench


def read_lcm_log(path, config: HardwareConfig, tolerance_s: float = 0.002):
    """Returns (table, report)."""
    import lcm  # noqa: PLC0415 (lcm only to read lcm-logger files)

    n = config.n_joints
    joints, wrenches, malformed = [], [], 0
    for event in lcm.EventLog(str(path), "r"):
        try:
            if event.channel == config.joint_state_channel:
                s = decode_joint_state(config.joint_state_type, event.data)
                if len(s.q) != n or s.v is None:
                    raise ValueError("joint count")
                joints.append(np.r_[s.t, s.q, s.v])
            elif event.channel == config.ft_channel:
                w = decode_wrench(event.data)
                wrenches.append(np.r_[w.t, w.wrench])
        except (ValueError, struct.error):
            malformed += 1
    if not wrenches or not joints:
        raise LogError(f"{path}: no {config.ft_channel} or {config.joint_state_channel} messages")
    jcols = [TIME, *joint_columns(Q, n), *joint_columns(QD, n)]
    jt = pd.DataFrame(np.array(joints), columns=jcols).sort_values(TIME)
    jt["_joint_index"] = np.arange(len(jt))
    ft = pd.DataFrame(np.array(wrenches), columns=[TIME, *wrench_columns(MEASURED)])
    ft = ft.sort_values(TIME)
    merged = pd.merge_asof(ft, jt, on=TIME, direction="backward", tolerance=tolerance_s)
    matched = merged["_joint_index"].notna()
    table = merged[matched].drop(columns="_joint_index")
    table = table[[TIME, *joint_columns(Q, n), *joint_columns(QD, n), *wrench_columns(MEASURED)]]
    used = set(merged.loc[matched, "_joint_index"].astype(int))
    report = {"ft": len(ft), "joint": len(jt), "rows": int(matched.sum()),
              "unmatched_ft": int((~matched).sum()), "unused_joint": len(jt) - len(used),
              "malformed": malformed}
    return table.reset_index(drop=True), report


def record_to_parquet(log_path, out_path, config: HardwareConfig, tolerance_s: float = 0.002):
    """read_lcm_log, then writes Parquet atomically. Returns the report."""
    table, report = read_lcm_log(log_path, config, tolerance_s)
    with atomic_path(out_path) as tmp:
        table.to_parquet(tmp, index=False)
    return report
