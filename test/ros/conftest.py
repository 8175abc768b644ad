# Copyright 2025 ring_gyro_sim developers
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

"""Fixtures of the node tests (the harness is in ``node_harness.py``)."""

import node_harness  # noqa: F401 - sets this session's ROS domain before rclpy starts
import pytest
import rclpy


@pytest.fixture(scope='session')
def ros():
    """Initialise rclpy once per session in this session's domain."""
    rclpy.init()
    yield
    rclpy.try_shutdown()
