"""serve's loop (cli/live.py): with ``batch_period_s`` it wakes at most once per that period
(each wake-up then handles every message that arrived); with 0 it spins again at once."""

import types

import pytest

from ftdrake.cli.live import serve_until_stopped


class CountingStation:
    """What serve_until_stopped reads of a station; counts the loop's wake-ups."""

    def __init__(self, batch_period_s: float):
        self.config = types.SimpleNamespace(batch_period_s=batch_period_s)
        self.monitor = types.SimpleNamespace(received={"joint": 0, "ft": 0})
        self.spins = 0

    def spin_once(self, timeout_ms: float) -> int:
        del timeout_ms  # nothing arrives: return at once
        self.spins += 1
        return 0

    def summary(self) -> dict:
        return {"latency_ms": {"p50": float("nan"), "p99": float("nan")}}


@pytest.mark.parametrize("batch", [0.05, 0.1])
def test_the_loop_wakes_at_most_once_per_batch_period(batch):
    station = CountingStation(batch)
    serve_until_stopped(station, duration_s=0.3, quiet=True)
    assert 1 <= station.spins <= round(0.3 / batch) + 1


def test_without_a_batch_period_the_loop_spins_again_at_once():
    station = CountingStation(0.0)
    serve_until_stopped(station, duration_s=0.3, quiet=True)
    assert station.spins > round(0.3 / 0.05) + 1
