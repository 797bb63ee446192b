"""Training as a library call: :func:`train` fits a compensator on a log as a
:class:`TrainOptions` says and returns it with its provenance (:class:`TrainResult`);
``ftdrake train`` is this call behind flags.

Layer: above ``compensation`` and ``data`` (it imports both), below ``cli``.
"""

from .options import TrainOptions, spelled_option
from .pipeline import TrainResult, train

__all__ = ["TrainOptions", "TrainResult", "spelled_option", "train"]
