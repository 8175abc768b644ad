"""MCAP recording and reading of runs as ROS 2 bags.

Modules (import from them directly, nothing is re-exported here):

- ``writer``: :class:`~ring_gyro_sim.recording.writer.BagWriter`, a ROS 2 bag writer that produces
  the same MCAP layout as rosbag2 (Jazzy, ``rosbag2_storage_mcap``);
- ``reader``: :func:`~ring_gyro_sim.recording.reader.read_messages`,
  :func:`~ring_gyro_sim.recording.reader.read_metadata` and
  :func:`~ring_gyro_sim.recording.reader.decode`, which also recover what a killed run left;
- ``schemas``: full ``ros2msg`` message definitions and type description hashes;
- ``errors``: :class:`~ring_gyro_sim.recording.errors.RecordingError`.
"""
