"""Tests of ftdrake.experiments."""
