"""Identifying a rigid payload on a wrist F/T sensor: the Newton–Euler regressor, weighted least
squares, the physically consistent program, the tether's pull, and the reports on what was
identified. Array math: no estimator here (the payload estimators in :mod:`..estimators` use
it)."""
