# Copyright 2026 ring_gyro_sim developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
MCAP recording and reading of runs as ROS 2 bags.

Modules (import from them directly, nothing is re-exported here):

- ``writer``: :class:`~ring_gyro_sim.recording.writer.BagWriter`, a ROS 2 bag writer that produces
  the same MCAP layout as rosbag2 (Jazzy, ``rosbag2_storage_mcap``);
- ``reader``: :func:`~ring_gyro_sim.recording.reader.read_messages`,
  :func:`~ring_gyro_sim.recording.reader.read_metadata` and
  :func:`~ring_gyro_sim.recording.reader.decode`, which also read what a killed run left, and
  :func:`~ring_gyro_sim.recording.reader.block_end_times_ns` (where the blocks of a recorded
  run ended, for re-simulation);
- ``recover``: :func:`~ring_gyro_sim.recording.recover.recover` (``ring_gyro recover``), a
  complete copy of a killed recording that every MCAP reader opens;
- ``schemas``: full ``ros2msg`` message definitions and type description hashes;
- ``cdr``: the CDR of the block messages and of ``~/rate``'s Imu packed from their numbers
  (what an offline recording writes, as rclpy serialises them);
- ``errors``: :class:`~ring_gyro_sim.recording.errors.RecordingError` and its subclasses
  ``OutputExistsError``, ``OutputBusyError``.
"""

__all__ = ['cdr', 'errors', 'reader', 'schemas', 'writer']
