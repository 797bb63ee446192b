"""Experiments built from the library: the demo and the RF-vs-SVR study."""
