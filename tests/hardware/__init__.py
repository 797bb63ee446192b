"""Tests of ftdrake.hardware: the live LCM station, its messages and recordings."""
