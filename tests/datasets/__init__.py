"""Tests of ftdrake.data (named apart from tests/data, the test data files)."""
