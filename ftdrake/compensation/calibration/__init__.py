"""Calibration of a wrist F/T sensor from a table of static poses (``ftdrake calibrate``):
reading the table, the gain/cross-talk correction, and the static payload model of a table
that gives the sensor's orientation directly."""
