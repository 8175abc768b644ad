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
The rate test's subscriber: ``~/rate`` with rclpy's ``qos_profile_sensor_data``.

``python rate_listener.py TOPIC``: one rclpy node with a best-effort, keep-last-5 subscription
(what a sensor-fusion node subscribes with) that notes, for every message it gets, its stamp
and the middleware's source timestamp (when the publisher sent it, ns of the system clock).
SIGINT ends it and prints one JSON line: ``{"stamps_ns": [...], "sent_ns": [...]}`` in
arrival order.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import json
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu
# isort: on


class RateListener(Node):
    """Subscribe to a ``sensor_msgs/Imu`` topic as a sensor-fusion node does."""

    def __init__(self, topic):
        super().__init__('rate_listener')
        self.stamps = []
        self.sent = []
        self.create_subscription(Imu, topic, self.note, qos_profile_sensor_data)

    def note(self, msg, info):
        self.stamps.append(msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec)
        self.sent.append(info['source_timestamp'])


def main():
    rclpy.init()
    node = RateListener(sys.argv[1])
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(json.dumps({'stamps_ns': node.stamps, 'sent_ns': node.sent}), flush=True)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
