"""Learning control outside the compensators: time-indexed iterative learning control."""

from .ilc import TimeIndexedFeedforward, ilc_update, q_filter

__all__ = ["TimeIndexedFeedforward", "ilc_update", "q_filter"]
