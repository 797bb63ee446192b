"""The simulation rig: one Drake system a module, each documenting its ports (sizes, units,
frames). ``ft_sensor`` (the ideal sensor at the weld), ``noisy_sensor`` (a real sensor's
imperfections), ``contact_truth``, ``controller``, ``friction``, ``tool_push``,
``sensor_gravity``, ``learned_feedforward``, ``time_indexed_feedforward`` and
``wrench_arrows`` (Meshcat). What runs on a live robot is in :mod:`ftdrake.runtime`."""
