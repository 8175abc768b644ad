"""MCAP recording and reading of runs as ROS 2 bags."""
