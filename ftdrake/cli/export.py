"""``ftdrake export``: a saved compensator → ONNX, for controllers outside Python.

    ftdrake export --model m.ftd --out m.onnx
"""

from __future__ import annotations

import json

from ..errors import ModelFileError
from . import args as a


def register(sub) -> None:
    """Adds ``export`` to an ``argparse`` subparsers object."""
    p = a.add_command(sub, "export", "a saved compensator → ONNX",
                      "For controllers outside Python.")
    a.add_model_file(p, required=True)
    p.add_argument("--out", type=a.output_file, required=True, metavar="FILE",
                   help="FILE.onnx")
    p.set_defaults(run=run_export)


def run_export(args) -> int:
    from ..compensation.estimators.base import Compensator
    from ..compensation.files.onnx_export import export_onnx
    from ..compensation.files.persistence import load_model

    with a.naming("--model", args.model):
        model = load_model(args.model)
    if type(model).onnx_parts is Compensator.onnx_parts:  # the base class: no export
        raise ModelFileError(f"--model {args.model}: a {type(model).__name__} has no ONNX "
                             "export; forests (rf) and SVRs (svr) have one")
    path = export_onnx(model, args.out)
    print(json.dumps({"out": str(path), "input": f"X float64 (N x {3 * model.n_joints_}) "
                      "= [q, qd, qdd]", "output": f"float64 (N x {model.n_outputs_})"}))
    return 0
