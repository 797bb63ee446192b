"""Compensators: estimators that predict the internal wrench from joint states.

The parts, bottom-up (a part imports only the parts below it; ``tests/test_layers.py``
checks it):

* :mod:`.features` (the one input layout every compensator takes) and :mod:`.contract` (what
  the runtime chain needs of a fitted model);
* :mod:`.compiled` (the compiled per-row paths the loop runs), :mod:`.identification` (the
  payload's rigid-body identification: regressors, least squares, the physically consistent
  program, the tether) and :mod:`.evaluation` (metrics, trust, scoring a fitted model), none
  of which imports another;
* :mod:`.estimators`: the compensators (scikit-learn estimators), their registry, how
  ``train`` builds them, and their tuning;
* :mod:`.calibration` (the calibration from a table of static poses, ``ftdrake calibrate``)
  and :mod:`.files` (model files and the ONNX export).
"""
