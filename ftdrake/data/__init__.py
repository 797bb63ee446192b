"""Data files: datasets ftdrake writes, and robot logs (tables, ROS bags) it reads."""
