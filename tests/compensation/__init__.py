"""Tests of ftdrake.compensation: the models, their identification, evaluation and files."""
