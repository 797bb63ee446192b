"""A long run's stages print what each is doing as it starts and its wall time as it ends
(the demo's console), and the times kept are those printed."""

import io
import json

from ftdrake.experiments.demo import REAL_TIME_FACTOR, print_table
from ftdrake.experiments.stages import Stages
from tests.helpers import ROOT


class Clock:
    """A wall clock that advances only when told (s)."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_each_stage_says_what_it_does_then_its_time():
    clock, out = Clock(), io.StringIO()
    stages = Stages(3, label="[demo]", stream=out, clock=clock)
    stages.start("collect", "simulating 16 runs")
    clock.now += 21.94
    stages.start("train", "fitting two models")
    clock.now += 120.0
    assert stages.times() == {"collect": 21.94, "train": 120.0}  # the running one: until now
    stages.start("write", "writing files")
    clock.now += 4.3
    assert stages.finish() == 21.94 + 120.0 + 4.3
    assert out.getvalue().splitlines() == [
        "[demo] 1/3 collect: simulating 16 runs …",
        "[demo] 1/3 collect done in 21.9 s",
        "[demo] 2/3 train: fitting two models …",
        "[demo] 2/3 train done in 120.0 s",
        "[demo] 3/3 write: writing files …",
        "[demo] 3/3 write done in 4.3 s",
        "[demo] done in 146.2 s: collect 21.9 s, train 120.0 s, write 4.3 s"]
    assert stages.times() == {"collect": 21.94, "train": 120.0, "write": 4.3}


def test_quiet_stages_print_nothing_and_keep_the_times():
    clock, out = Clock(), io.StringIO()
    stages = Stages(1, label="[x]", progress=False, stream=out, clock=clock)
    stages.start("only", "a thing")
    clock.now += 2.0
    stages.finish()
    assert out.getvalue() == "" and stages.times() == {"only": 2.0}


def test_the_demo_table_says_what_the_real_time_factor_is(capsys):
    summary = json.loads((ROOT / "docs" / "demo" / "summary.json").read_text())
    print_table(summary)
    lines = capsys.readouterr().out.splitlines()
    row = next(x for x in lines if x.strip().startswith("real-time factor"))
    assert row.rstrip().endswith("×") and "¹" in row
    note = next(x for x in lines if x.strip().startswith("¹"))
    assert REAL_TIME_FACTOR in note and "seconds of the contact run simulated per second of " \
        "wall time" in note
