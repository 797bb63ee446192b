"""Makes the small UR3 test files in this folder from /work/shared/realdata/ur3 (run by hand).

    python tests/data/ur3/make_data.py [SOURCE_DIR]

* ``id1.csv``, ``id2.csv``: the first ``ROWS`` samples (native ~125 Hz, not resampled) of the
  identification trajectories id1.mat and id2.mat, as columns ``t`` (s), ``q_0..q_5`` (rad),
  ``qd_0..qd_5`` (rad/s), ``tau_0..tau_5`` (N·m, measured joint torques); values rounded to
  1e-6, the precision the robot reports.
* ``prbs.csv``: the same columns, the first ``ROWS`` samples of the pseudo-random binary
  trajectory prbs.mat (keys ``time``, ``q``, ``d_q``, ``m_torque``; its ``d_d_q`` is left out,
  as in the other copies: a reader differentiates q̇).
* ``ur3_2019-11-27-11-55-35.bag``: the whole ROS 1 bag (2179 messages, 17.4 s), every
  message copied byte for byte (same topic ``/arm``, type, definition, receive times) into
  BZ2-compressed chunks: 158 kB instead of 655 kB.

The tests read only these copies, never the source folder.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pandas as pd
from rosbags.rosbag1 import Reader, Writer
from scipy.io import loadmat

HERE = Path(__file__).resolve().parent
SOURCE = Path("/work/shared/realdata/ur3")
BAG = "ur3_2019-11-27-11-55-35.bag"
ROWS = 750  # 6 s at 125 Hz


#: Each recording's keys: time, q, q̇, measured torque.
KEYS = {"id": ("mt", "mq", "mdq", "mtorque"), "prbs": ("time", "q", "d_q", "m_torque")}


def write_csv(mat: Path, out: Path, keys=KEYS["id"]) -> None:
    d = loadmat(mat)
    time, q, qd, tau = keys
    blocks = {"q": d[q], "qd": d[qd], "tau": d[tau]}
    frame = pd.DataFrame({"t": d[time].ravel()[:ROWS]})
    for prefix, values in blocks.items():
        for j in range(values.shape[1]):
            frame[f"{prefix}_{j}"] = values[:ROWS, j]
    frame.to_csv(out, index=False, float_format="%.6f")


def write_bag(src: Path, out: Path) -> None:
    out.unlink(missing_ok=True)
    writer = Writer(out)
    writer.set_compression(Writer.CompressionFormat.BZ2)  # before opening
    with Reader(src) as reader, writer:
        copies = {}
        for conn in reader.connections:
            copies[conn.id] = writer.add_connection(
                conn.topic, conn.msgtype, msgdef=conn.msgdef.data, md5sum=conn.digest,
                callerid=conn.ext.callerid, latching=conn.ext.latching,
            )
        for conn, stamp, raw in reader.messages():
            writer.write(copies[conn.id], stamp, raw)


def main(source: Path = SOURCE) -> None:
    write_csv(source / "id1.mat", HERE / "id1.csv")
    write_csv(source / "id2.mat", HERE / "id2.csv")
    write_csv(source / "prbs.mat", HERE / "prbs.csv", KEYS["prbs"])
    write_bag(source / BAG, HERE / BAG)
    shutil.copyfile(source / "LICENSE", HERE / "LICENSE")
    for f in sorted(HERE.iterdir()):
        print(f"{f.name:20s} {f.stat().st_size / 1e3:8.1f} kB")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else SOURCE)
