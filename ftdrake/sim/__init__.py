"""The simulation: scene, trajectories, the station (one diagram), running it, evaluating it
against ground truth, and collecting datasets."""
