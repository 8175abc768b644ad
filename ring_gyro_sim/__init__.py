"""ring_gyro_sim: a ROS 2 emulator of a capacitive MEMS vibrating-ring gyroscope under shock."""

__version__ = '0.1.0'
