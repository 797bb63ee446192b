"""Tests of ftdrake.config."""
