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
The flood test's reference subscriber: receives a shock topic and drains it undecoded.

``python raw_drain.py TOPIC``: one rclpy node with a subscription of the node's shock QoS
(``ros.qos.SHOCK_QOS``) on TOPIC, taken undecoded by the executor (one per wait) and by a
10 ms timer that takes every waiting message raw, as the node's drain takes a flood's excess
(``ros/node.py``, ``_drain_inputs``), both counted. Its CPU time per message is what
receiving a flood costs any rclpy process on this host: the unit in which ``test_node.py``
judges what the flood costs the node. SIGINT ends it and prints the count.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import sys

from geometry_msgs.msg import Vector3Stamped
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from ring_gyro_sim.ros.qos import SHOCK_QOS
# isort: on


class RawDrain(Node):
    """Subscribe to a topic and take its messages undecoded every 10 ms."""

    def __init__(self, topic):
        super().__init__('flood_reference')
        self.taken = 0
        self.sub = self.create_subscription(Vector3Stamped, topic, self.count, SHOCK_QOS,
                                            raw=True)
        self.create_timer(0.01, self.drain)

    def count(self, msg):
        self.taken += 1

    def drain(self):
        while True:
            with self.sub.handle:
                taken = self.sub.handle.take_message(self.sub.msg_type, True)
            if taken is None:
                return
            self.taken += 1


def main():
    rclpy.init()
    node = RawDrain(sys.argv[1])
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(f'taken {node.taken}', flush=True)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
