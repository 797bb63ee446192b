"""Tests of ftdrake.runtime: the chain and its systems."""
