"""Rigid-body physics independent of the simulation: sensor-frame kinematics (Drake's, in
``rigid_body``, and compiled for serial chains, in ``chain``), Newton–Euler wrenches, robot
descriptions (``robot``)."""
