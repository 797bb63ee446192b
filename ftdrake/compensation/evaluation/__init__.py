"""Scoring predictions: the per-axis metrics, which predictions not to trust, and the report of
``ftdrake evaluate``. Works on any fitted model's predictions (no estimator is imported here;
the estimators use the metrics)."""
