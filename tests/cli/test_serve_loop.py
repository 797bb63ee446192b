"""serve's loop (cli/live.py): with ``batch_period_s`` it wakes at most once per that period
(each wake-up then handles every message that arrived); with 0 it spins again at once. Its
status line and summary give serve's own CPU per processed F/T message and share of a core."""

import io
import os
import types

import numpy as np
import pytest

from ftdrake.cli import live
from ftdrake.cli.live import Status, serve_until_stopped
from ftdrake.hardware.overload import cpu_use


class CountingStation:
    """What serve_until_stopped reads of a station; counts the loop's wake-ups."""

    def __init__(self, batch_period_s: float):
        self.config = types.SimpleNamespace(batch_period_s=batch_period_s)
        self.monitor = types.SimpleNamespace(received={"joint": 0, "ft": 0})
        self.processed = 0
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


class FakeCpu:
    """The process's CPU clock (s), advanced by hand."""

    def __init__(self):
        self.s = 10.0

    def __call__(self) -> float:
        return self.s


def test_cpu_use_is_cpu_time_per_message_and_per_wall_second():
    assert cpu_use(0.05, 0.5, 500) == pytest.approx({"core_percent": 10.0,
                                                     "us_per_message": 100.0})
    assert cpu_use(0.05, 0.5, 0) == {"core_percent": pytest.approx(10.0),
                                     "us_per_message": None}
    assert cpu_use(0.0, 0.0, 0) == {"core_percent": None, "us_per_message": None}


class ServingStation(CountingStation):
    """A station that processes `per_spin` F/T messages per spin, each costing `cost_s` of
    the fake CPU clock, and has what the status line reads."""

    def __init__(self, cpu: FakeCpu, per_spin: int, cost_s: float):
        super().__init__(0.0)
        self.cpu, self.per_spin, self.cost_s = cpu, per_spin, cost_s
        self.published = 0
        self.monitor.rejected, self.monitor.fault = {}, False
        self.load = types.SimpleNamespace(lost=0, dropped=0, backlog_s=0.0)

    def spin_once(self, timeout_ms: float) -> int:
        super().spin_once(timeout_ms)
        self.processed += self.per_spin
        self.monitor.received["ft"] += self.per_spin
        self.cpu.s += self.per_spin * self.cost_s
        return self.per_spin

    def output(self, _name: str):
        return np.zeros(1)


def test_the_summary_gives_the_cpu_per_processed_message_over_the_loop():
    cpu = FakeCpu()
    station = ServingStation(cpu, per_spin=3, cost_s=120e-6)
    summary = serve_until_stopped(station, duration_s=0.2, quiet=True, cpu_clock=cpu)
    assert station.processed > 0
    assert summary["cpu"]["us_per_message"] == pytest.approx(120.0)
    share = 100 * station.processed * 120e-6 / summary["wall_time_s"]
    assert summary["cpu"]["core_percent"] == pytest.approx(share)


def test_the_status_line_gives_the_cpu_since_the_last_line(monkeypatch):
    cpu = FakeCpu()
    station = ServingStation(cpu, per_spin=0, cost_s=0.0)
    stream = io.StringIO()
    status = Status(station, stream=stream, cpu_clock=cpu)
    station.processed, cpu.s = 400, cpu.s + 0.04  # 400 messages at 100 µs each
    monkeypatch.setattr(live, "STATUS_PERIOD_S", 0.0)
    status.maybe_print(status.last + 0.5)
    assert status.cpu_meter.latest == pytest.approx({"core_percent": 8.0,
                                                   "us_per_message": 100.0})
    assert "CPU 8 % (100 µs/msg)" in stream.getvalue()
    station.processed, cpu.s = 500, cpu.s + 0.03  # the next line: only what came since
    status.maybe_print(status.last + 0.5)
    assert "CPU 6 % (300 µs/msg)" in stream.getvalue().splitlines()[-1]


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("columns", [50, 80, 200])
def test_on_a_terminal_the_line_fits_its_width_keeping_the_state_and_the_contact(
        monkeypatch, columns):
    """Rewritten in place with a carriage return, a line wider than the terminal would wrap
    and leave its start behind at every update: on a terminal the line fits its width,
    dropping the counts before the state, the contact flag and the F/T rate."""
    cpu = FakeCpu()
    station = ServingStation(cpu, per_spin=0, cost_s=0.0)
    terminal = Terminal()
    status = Status(station, stream=terminal, cpu_clock=cpu)
    station.processed, station.published, cpu.s = 123456, 123456, cpu.s + 0.06
    monkeypatch.setattr(live.shutil, "get_terminal_size",
                        lambda: os.terminal_size((columns, 24)))
    status.maybe_print(status.last + 0.5)
    line = terminal.getvalue()
    assert line.endswith("\r") and "\n" not in line
    line = line[:-1]
    assert len(line) == columns - 1  # padded over what the last line left
    for kept in ("ok", "contact no", "F/T"):
        assert kept in line
    assert ("published 123456" in line) == (columns == 200)
    assert ("CPU 12 % (0 µs/msg)" in line) == (columns >= 80)


def test_in_a_log_the_line_is_whole():
    cpu = FakeCpu()
    station = ServingStation(cpu, per_spin=0, cost_s=0.0)
    log = io.StringIO()
    status = Status(station, stream=log, cpu_clock=cpu)
    station.processed = station.published = 123456
    status.maybe_print(status.last + 0.5)
    line = log.getvalue()
    assert line.endswith("\n") and line.count("\n") == 1
    for field in ("joint", "F/T", "processed 123456", "published 123456", "rejected 0",
                  "lost 0", "dropped 0", "behind 0 ms", "ok", "contact no", "CPU 0 %"):
        assert field in line
