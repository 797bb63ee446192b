"""Tests of the repository as a whole: the docs build, the examples, the wheel, the import
layers, the tests' own layout, a new user's path end to end."""
