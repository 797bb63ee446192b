"""Tests of ftdrake.cli: the commands, run in-process."""
