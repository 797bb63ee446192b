"""Learning control outside the compensators: time-indexed iterative learning control."""

from .ilc import ilc_update, q_filter

__all__ = ["ilc_update", "q_filter"]
