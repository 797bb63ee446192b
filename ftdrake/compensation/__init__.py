"""Compensators: estimators that predict the internal wrench from joint states."""
