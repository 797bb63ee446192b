"""Tests of ftdrake.control."""
