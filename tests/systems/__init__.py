"""Tests of ftdrake.systems."""
