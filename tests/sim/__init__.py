"""Tests of ftdrake.sim."""
