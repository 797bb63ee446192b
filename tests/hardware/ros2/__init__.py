"""Tests of ftdrake.hardware.ros2."""
