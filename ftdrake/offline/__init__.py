"""Tools around the product, run offline: not part of the loop beside the robot.

``recorder`` (:func:`~ftdrake.offline.recorder.add_recorder`: the chain's signals and any
diagram's as a log, in the layout every reader takes; the stations and ``simulate`` record
with it), ``replay`` (:func:`~ftdrake.offline.replay.replay`: the runtime chain run over a
log, row by row, as the live station runs it), ``thresholds`` (the detector's thresholds from
a false-positive budget on a free-motion run) and ``residual_budget`` (a replay's in-motion
residual split into its sources). They import the runtime chain and nothing of the
simulation (``systems``, ``sim``) or the experiments; the live stations may import them.
Importing this package loads none of its modules: import the module you need.
"""
