"""What a model file's manifest keeps about the training run that made it (its ``extra``)."""

from __future__ import annotations

from ..compensation.evaluation.evaluation import target_ranges
from ..data.training import TrainingData


def provenance(path, data: TrainingData, model, search, *, kind: str,
               time_window=(None, None), dask: str | None = None) -> dict:
    """What the manifest's ``extra`` keeps about a training run on `data` read from `path`:
    the data (file, kind, source, read options, time window), its columns and how computed
    ones were derived, the training ranges of time and targets (those of the inputs are the
    manifest's ``input_range``), the row counts, the reader's warnings, the model's kind and
    parameters (a domain-calibrated hybrid's: the hybrid's) and the search's result."""
    estimator = getattr(model, "estimator_", model)  # a wrapper's: the wrapped model's
    return {
        "data": {
            "file": str(path),
            "kind": data.kind,
            "source": data.source,
            "options": data.options.to_dict(),
            "time_window_s": list(time_window),
        },
        "columns": {
            "joints": data.joint_names,
            "targets": data.target_names,
            "temperature": data.options.temperature if data.has_temperature else None,
            "derived": data.derivation,
        },
        "training_range": {
            "t_s": [float(data.t.min()), float(data.t.max())],
            "targets": target_ranges(data.Y, data.target_names),
            "inputs": "see the manifest's input_range",
        },
        "rows": data.rows,
        "reader_warnings": data.warnings,
        "model": {"kind": kind, "params": plain(estimator.get_params(deep=False))},
        "tuning": search.to_dict() if search is not None else None,
        "dask": dask,
    }


def plain(params: dict) -> dict:
    """The JSON-friendly parameters (numbers, strings, lists of them); others by type name."""
    out = {}
    for k, v in params.items():
        if k == "robot" and isinstance(v, str) and v.lstrip().startswith("directives:"):
            out[k] = "<model directives of the training data's robot>"
        elif v is None or isinstance(v, (bool, int, float, str)):
            out[k] = v
        elif isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
            out[k] = list(v)
        else:
            out[k] = type(v).__name__
    return out
