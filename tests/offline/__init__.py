"""Tests of ftdrake.offline: replay, the recorder, threshold calibration, the residual
budget."""
