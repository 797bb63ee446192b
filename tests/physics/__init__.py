"""Tests of ftdrake.physics."""
