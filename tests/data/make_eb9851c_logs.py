"""How log_eb9851c.parquet and replay_eb9851c.csv were made: run at commit eb9851c (the log
layout before the signal table, format 1) as

    git checkout eb9851c && python3 tests/data/make_eb9851c_logs.py tests/data

log_eb9851c.parquet: 0.25 s of the contact scenario with the bias tracker following the payload,
its change monitor and a re-tare, every 5th row, saved with ``save_dataset``; it has every
column of that release (``pred_*``, ``est_external_*``, ``detected``, the truth ``contact`` …).
replay_eb9851c.csv: ``replay`` of 0.1 s of the contact scenario, written as ``ftdrake replay
--out x.csv`` wrote it (``DataFrame.to_csv``). Both read with today's names in
tests/test_signal_vocabulary.py.
"""

import sys
from pathlib import Path

from ftdrake import ScenarioConfig, replay, save_dataset
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station
from ftdrake.testing import fit_forest


def main(out: Path) -> None:
    scenario = ScenarioConfig()
    scenario.trajectory.kind = "contact"
    scenario.bias_tracker.track_payload = True
    scenario.bias_tracker.payload_change.enabled = True
    scenario.events.retare_at_s = 0.1
    scenario.validate()
    model = fit_forest(scenario, duration=0.3)
    log = simulate(build_station(scenario, model), progress=False, duration=0.25).log
    save_dataset(log.iloc[::5].reset_index(drop=True), out / "log_eb9851c.parquet")

    scenario = ScenarioConfig()
    scenario.trajectory.kind = "contact"
    scenario.validate()
    model = fit_forest(scenario, duration=0.3)
    log = simulate(build_station(scenario), progress=False, duration=0.1).log
    replay(model, log, scenario).to_csv(out / "replay_eb9851c.csv", index=False)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
