"""Rigid-body physics independent of the simulation: sensor-frame kinematics, Newton–Euler
wrenches, robot descriptions."""
